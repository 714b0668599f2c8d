#include "child_process.hpp"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <fstream>
#include <sstream>
#include <thread>

#include "st/common/error.hpp"

extern char** environ;

namespace st::astro::detail {
namespace {

bool isExecutableFile(const std::string& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode) && ::access(path.c_str(), X_OK) == 0;
}

/// Stops the whole group: SIGTERM, up to 2 s for it to end, then SIGKILL; reaps the child.
void stopGroup(pid_t pid) {
  ::kill(-pid, SIGTERM);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(2);
  int status = 0;
  while (std::chrono::steady_clock::now() < deadline) {
    if (::waitpid(pid, &status, WNOHANG) == pid) {
      ::kill(-pid, SIGKILL);  // grandchildren that outlived it (solve-field's astrometry-engine)
      return;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ::kill(-pid, SIGKILL);
  ::waitpid(pid, &status, 0);
}

}  // namespace

std::string findProgram(const std::string& program) {
  if (program.empty()) return {};
  if (program.find('/') != std::string::npos) return isExecutableFile(program) ? program : std::string{};
  const char* path = std::getenv("PATH");
  std::stringstream dirs(path != nullptr ? path : "/usr/local/bin:/usr/bin:/bin");
  std::string dir;
  while (std::getline(dirs, dir, ':')) {
    const std::string candidate = (dir.empty() ? std::string(".") : dir) + "/" + program;
    if (isExecutableFile(candidate)) return candidate;
  }
  return {};
}

ChildResult runChild(const std::vector<std::string>& argv, const std::string& stdoutPath,
                     const std::string& stderrPath, double timeLimitS, ProgressSink& progress,
                     CancelToken& cancel, const std::string& stage) {
  if (argv.empty()) throw InputError("no program to run");
  std::vector<char*> args;
  std::vector<std::string> copies(argv);
  for (auto& a : copies)
    args.push_back(a.data());
  args.push_back(nullptr);

  posix_spawn_file_actions_t actions;
  posix_spawnattr_t attr;
  posix_spawn_file_actions_init(&actions);
  posix_spawnattr_init(&attr);
  posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, stdoutPath.c_str(), O_WRONLY | O_CREAT | O_TRUNC,
                                   0644);
  posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, stderrPath.c_str(), O_WRONLY | O_CREAT | O_TRUNC,
                                   0644);
  posix_spawnattr_setpgroup(&attr, 0);  // its own group, so that a stop reaches its children too
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETPGROUP);
  pid_t pid = 0;
  const int rc = ::posix_spawnp(&pid, args[0], &actions, &attr, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  posix_spawnattr_destroy(&attr);
  if (rc != 0) throw InputError("cannot start " + argv[0] + ": " + std::strerror(rc));

  ChildResult result;
  const auto start = std::chrono::steady_clock::now();
  for (;;) {
    int status = 0;
    const pid_t done = ::waitpid(pid, &status, WNOHANG);
    result.elapsedS = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (done == pid) {
      result.exitCode = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
      ::kill(-pid, SIGKILL);  // nothing of the group may outlive it
      return result;
    }
    if (done < 0 && errno != EINTR) {
      stopGroup(pid);
      throw InputError("lost track of " + argv[0] + ": " + std::strerror(errno));
    }
    if (cancel.cancelled()) {
      stopGroup(pid);
      throw Cancelled();
    }
    if (result.elapsedS > timeLimitS) {
      stopGroup(pid);
      result.timedOut = true;
      return result;
    }
    progress.report(std::min(1.0, result.elapsedS / timeLimitS), stage);
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
}

std::string tailOfFile(const std::string& path, int maxLines) {
  std::ifstream in(path);
  std::deque<std::string> lines;
  std::string line;
  while (std::getline(in, line)) {
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    lines.push_back(line);
    if (static_cast<int>(lines.size()) > maxLines) lines.pop_front();
  }
  std::string out;
  for (const auto& l : lines)
    out += (out.empty() ? "" : "\n") + l;
  return out;
}

}  // namespace st::astro::detail

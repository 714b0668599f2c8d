#pragma once
// Running the built synthtrack-cli from the app tests (they skip when it was not built).
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace st::test {

/// The synthtrack-cli next to the tests (build/app), or empty when it was not built.
inline std::filesystem::path cliPath() {
  // Tests run in build/tests (WORKING_DIRECTORY of gtest_discover_tests); the CLI is build/app.
  for (const char* p : {"../app/synthtrack-cli", "app/synthtrack-cli", "../../app/synthtrack-cli"}) {
    if (std::filesystem::exists(p)) return std::filesystem::absolute(p);
  }
  return {};
}

/// Runs the CLI with `args` (already quoted where needed, redirections included); returns its exit
/// status. Built with append, not operator+, which trips GCC 12's -Wrestrict false positive.
inline int runCli(const std::filesystem::path& cli, const std::string& args) {
  std::string cmd;
  cmd.append("\"").append(cli.string()).append("\" ").append(args);
  const int status = std::system(cmd.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

/// `p` in double quotes, for a shell command line.
inline std::string quoted(const std::filesystem::path& p) {
  std::string s;
  s.append("\"").append(p.string()).append("\"");
  return s;
}

/// The whole text of a file ("" when it cannot be read).
inline std::string readText(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

/// The "timings: " lines of a --timings run's stderr, saved in `p`, in order.
inline std::vector<std::string> timingLines(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);)
    if (line.rfind("timings: ", 0) == 0) lines.push_back(line);
  return lines;
}

/// How many of `order` the lines name in that order (each in a line after the previous one's).
inline std::size_t stepsInOrder(const std::vector<std::string>& lines,
                                const std::vector<std::string>& order) {
  std::size_t at = 0;
  for (const auto& s : lines)
    if (at < order.size() && s.find(order[at]) != std::string::npos) ++at;
  return at;
}

}  // namespace st::test

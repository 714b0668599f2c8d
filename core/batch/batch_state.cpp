#include "st/batch/batch_state.hpp"

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <fstream>

#include "st/common/error.hpp"
#include "st/common/fnv1a.hpp"

namespace st::batch {

namespace fs = std::filesystem;

namespace {

struct Fnv1a {
  std::uint64_t h = kFnv1aBasis;
  void add(const std::string& s) {
    h = fnv1a(s.data(), s.size(), h);
    constexpr unsigned char kSeparator = 0xff;  // ("ab", "c") differs from ("a", "bc")
    h = fnv1a(&kSeparator, 1, h);
  }
};

void addFiles(Fnv1a& f, const char* what, const std::vector<std::string>& paths) {
  f.add(what);
  for (const auto& in : paths) {
    std::vector<std::string> files{in};
    std::error_code ec;
    if (fs::is_directory(in, ec)) {
      try {
        files = framesInFolder(in);
      } catch (const InputError&) {
        files.clear();
      }
      f.add("folder " + in);
    }
    for (const auto& file : files) {
      f.add(file);
      const auto size = fs::file_size(file, ec);
      if (ec) {
        f.add("missing");
        continue;
      }
      const auto mtime = fs::last_write_time(file, ec).time_since_epoch();
      f.add(std::to_string(size) + " " +
            std::to_string(std::chrono::duration_cast<std::chrono::nanoseconds>(mtime).count()));
    }
  }
}

/// ".NAME<what>PID" (append, not operator+: GCC 12's -Wrestrict false positive).
std::string hiddenName(const fs::path& dir, const char* what) {
  std::string n = ".";
  n.append(dir.filename().string()).append(what).append(std::to_string(::getpid()));
  return n;
}

}  // namespace

std::string inputDigest(const Observation& obs, const std::map<std::string, std::string>& params) {
  Fnv1a f;
  addFiles(f, "inputs", obs.inputs);
  addFiles(f, "bias", obs.bias);
  addFiles(f, "dark", obs.dark);
  addFiles(f, "flat", obs.flat);
  f.add("params");
  for (const auto& [k, v] : params)
    f.add(k + "=" + v);
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(f.h));
  return buf;
}

nlohmann::json readJsonFile(const fs::path& path) {
  std::ifstream in(path);
  if (!in) throw InputError("cannot read '" + path.string() + "'");
  try {
    nlohmann::json j;
    in >> j;
    return j;
  } catch (const nlohmann::json::exception& e) {
    throw InputError("'" + path.string() + "' is not valid JSON: " + e.what());
  }
}

bool outputComplete(const fs::path& dir, const std::string& digest) {
  std::error_code ec;
  if (!fs::is_regular_file(dir / kDigestFile, ec) || !fs::is_regular_file(dir / kResultFile, ec))
    return false;
  try {
    const nlohmann::json j = readJsonFile(dir / kDigestFile);
    return j.value("digest", std::string()) == digest;
  } catch (const InputError&) {
    return false;
  }
}

void writeJsonAtomically(const fs::path& path, const nlohmann::json& json) {
  const fs::path tmp = path.string() + ".tmp-" + std::to_string(::getpid());
  {
    std::ofstream out(tmp);
    if (!out) throw InputError("cannot write '" + tmp.string() + "'");
    out << json.dump(2) << '\n';
    out.flush();
    if (!out) throw InputError("error writing '" + tmp.string() + "'");
  }
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec)
    throw InputError("cannot rename '" + tmp.string() + "' to '" + path.string() + "': " + ec.message());
}

StagedFolder::StagedFolder(fs::path finalDir) : m_final(std::move(finalDir)) {
  m_staging = m_final.parent_path() / hiddenName(m_final, ".tmp-");
  std::error_code ec;
  fs::remove_all(m_staging, ec);
  fs::create_directories(m_staging, ec);
  if (ec) throw InputError("cannot create '" + m_staging.string() + "': " + ec.message());
}

StagedFolder::~StagedFolder() {
  if (m_committed) return;
  std::error_code ec;
  fs::remove_all(m_staging, ec);
}

void StagedFolder::commit() {
  std::error_code ec;
  fs::path aside;
  if (fs::exists(m_final, ec)) {
    aside = m_final.parent_path() / hiddenName(m_final, ".old-");
    fs::remove_all(aside, ec);
    fs::rename(m_final, aside, ec);
    if (ec) throw InputError("cannot move the old '" + m_final.string() + "' aside: " + ec.message());
  }
  fs::rename(m_staging, m_final, ec);
  if (ec)
    throw InputError("cannot rename '" + m_staging.string() + "' to '" + m_final.string() +
                     "': " + ec.message());
  m_committed = true;
  if (!aside.empty()) fs::remove_all(aside, ec);
}

}  // namespace st::batch

#pragma once
// What makes a batch restartable (issue 17): each observation's outputs go to a staging folder that is
// renamed into place when complete, with a digest of its inputs and parameters; a rerun skips an
// observation whose folder holds the same digest and redoes the others.
#include <filesystem>
#include <map>
#include <string>

#include <nlohmann/json.hpp>

#include "st/batch/observation_list.hpp"

namespace st::batch {

/// The file that marks an observation's output folder complete; written last, before the rename.
inline constexpr const char* kDigestFile = "digest.json";
/// The search result of an observation (the JSON of `synthtrack-cli search --fit --json`).
inline constexpr const char* kResultFile = "candidates.json";

/// Layout of a batch's output folder DIR: DIR/observations/NAME (one per observation), DIR/logs/NAME.json
/// (a log per observation: status, rank, host, seconds, error), DIR/catalogue.json.
struct BatchLayout {
  std::filesystem::path root;
  [[nodiscard]] std::filesystem::path observationDir(const std::string& name) const {
    return root / "observations" / name;
  }
  [[nodiscard]] std::filesystem::path logFile(const std::string& name) const {
    return root / "logs" / (name + ".json");
  }
  [[nodiscard]] std::filesystem::path catalogue() const { return root / "catalogue.json"; }
};

/// A digest (16 hex digits, FNV-1a 64) of what an observation's result depends on: every input and
/// calibration file's path, size and modification time (folders expanded), and `params` (the effective
/// search options). Files that do not exist enter as "missing" (the digest still changes once they do).
std::string inputDigest(const Observation& obs, const std::map<std::string, std::string>& params);

/// Whether `dir` is a complete output for `digest`: its digest file holds it and the result file is there.
bool outputComplete(const std::filesystem::path& dir, const std::string& digest);

/// An output folder written in a staging folder next to its final place (".NAME.tmp-PID") and renamed
/// into place by commit(); a folder that was never committed is removed when this object goes (an
/// interrupted run leaves at worst a stale staging folder, never a half-written final one).
class StagedFolder {
 public:
  /// Creates the staging folder for `finalDir` (its parent is created too). Throws st::InputError.
  explicit StagedFolder(std::filesystem::path finalDir);
  ~StagedFolder();
  StagedFolder(const StagedFolder&) = delete;
  StagedFolder& operator=(const StagedFolder&) = delete;
  /// Where to write the files.
  [[nodiscard]] const std::filesystem::path& path() const noexcept { return m_staging; }
  /// Replaces the final folder (an older one is renamed aside first, then removed). Throws st::InputError.
  void commit();

 private:
  std::filesystem::path m_final;
  std::filesystem::path m_staging;
  bool m_committed = false;
};

/// Writes `json` (pretty-printed) to `path` through a temporary file and a rename. Throws st::InputError.
void writeJsonAtomically(const std::filesystem::path& path, const nlohmann::json& json);

/// Reads a JSON file; throws st::InputError naming it when it cannot be read or parsed.
nlohmann::json readJsonFile(const std::filesystem::path& path);

}  // namespace st::batch

#pragma once
// One observation of a batch on this process (issue 17): skip it when its outputs are complete for the
// same inputs and parameters, else run it through the same pipeline as `search --fit`
// (observation_pipeline.hpp), write its folder atomically and its JSON log. Used by the one-process queue
// and by every MPI worker alike.
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "backend_factory.hpp"
#include "cli_args.hpp"
#include "st/batch/batch_state.hpp"
#include "st/batch/catalogue.hpp"
#include "st/batch/observation_list.hpp"

namespace st::app {

/// The batch-wide settings: the output layout and the search and load options as `search` takes them
/// (option name without "--" -> value, "" for a flag such as grid-step-fwhm or no-register).
struct BatchSettings {
  batch::BatchLayout layout;
  std::map<std::string, std::string> options;
};

/// The options in force for `obs`: the batch's, overridden by the observation's own.
std::map<std::string, std::string> effectiveOptions(const BatchSettings& settings,
                                                    const batch::Observation& obs);

/// `options` (name without "--" -> value) as the command-line arguments `search` parses.
CliArgs argsForOptions(const std::map<std::string, std::string>& options);

/// Checks `options` parse as `search` options (UsageError naming the one at fault) without running.
void validateOptions(const std::map<std::string, std::string>& options);

/// Who runs the observation, for its log.
struct WorkerInfo {
  int rank = 0;
  std::string host;
  std::string resources;  ///< e.g. "GPU 1 of 4, 16 CPU threads"
};

/// The result of one observation on this process.
struct RunOutcome {
  batch::Outcome outcome;
  bool skipped = false;  ///< complete outputs with the same digest were there
  double seconds = 0.0;
};

/// Keeps one search backend per (backend, method, frame precision) for the life of a worker (a CUDA backend
/// is costly to make).
class BackendCache {
 public:
  search::SearchBackend& get(const std::string& backend, search::SearchMethod method, std::string& message,
                             const std::string& framePrecision = "fp32");

 private:
  std::map<std::string, BackendSelection> m_backends;
};

/// Runs (or skips) `obs`: see the file comment. A failure (unreadable or corrupt input, a bad option) is
/// returned as Outcome::Status::Failed with the message and logged, never thrown; st::Cancelled is thrown.
/// `quiet`: no progress bar.
RunOutcome runBatchObservation(const batch::Observation& obs, const BatchSettings& settings,
                               BackendCache& backends, const WorkerInfo& worker);

/// Whether `obs` would be skipped (complete outputs for its digest); the outcome read from them when so.
bool completedEarlier(const batch::Observation& obs, const BatchSettings& settings, batch::Outcome& outcome);

/// The outcome of an observation another process ran, from its folder (Done) or its log (Failed);
/// NotDone with `reason` when neither says it finished.
batch::Outcome outcomeFromDisk(const batch::Observation& obs, const BatchSettings& settings,
                               const std::string& reason);

/// The line a stopped batch prints naming the observations not done, "batch: NOT DONE: a, b. Rerun ...", at
/// most `budget` bytes: the names that do not fit are counted ("... and N more (the catalogue lists every
/// one)"); "batch: every observation had finished" when there are none.
std::string notDoneLine(const std::vector<std::string>& names, std::size_t budget);

}  // namespace st::app

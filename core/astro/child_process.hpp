#pragma once
// Internal to core/astro: running an external program (astrometry.net's solve-field) without a shell.
#include <string>
#include <vector>

#include "st/common/progress.hpp"

namespace st::astro::detail {

/// Where `program` would be run from: itself when it contains '/', else the first executable match on PATH.
/// Empty when there is none.
std::string findProgram(const std::string& program);

struct ChildResult {
  int exitCode = -1;      ///< the exit status; -1 when killed
  bool timedOut = false;  ///< stopped at the time limit
  double elapsedS = 0.0;
};

/// Runs argv[0] (looked up on PATH) with `argv`, no shell, in its own process group, stdout and stderr
/// written to `stdoutPath` / `stderrPath`. Polls every 50 ms: past `timeLimitS` seconds of wall time the
/// group is stopped (SIGTERM, then SIGKILL after 2 s) and timedOut set; when `cancel` is set the group is
/// stopped the same way and st::Cancelled thrown. `progress` gets the elapsed fraction of the limit. Throws
/// st::InputError when the program cannot be started.
ChildResult runChild(const std::vector<std::string>& argv, const std::string& stdoutPath,
                     const std::string& stderrPath, double timeLimitS, ProgressSink& progress,
                     CancelToken& cancel, const std::string& stage);

/// The last `maxLines` non-empty lines of a text file (empty when unreadable).
std::string tailOfFile(const std::string& path, int maxLines);

}  // namespace st::astro::detail

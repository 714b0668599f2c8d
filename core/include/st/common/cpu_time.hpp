#pragma once
// The process's CPU time (every thread's), for stage timings beside their wall time.
#include <ctime>

namespace st {

/// CPU seconds of all the process's threads since it started (CLOCK_PROCESS_CPUTIME_ID).
inline double processCpuSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

}  // namespace st

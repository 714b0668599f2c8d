#pragma once
// What every benchmark prints about where and when it ran, and the process CPU time that tells contention
// on a shared machine apart from slow code.
#include <string>

#include "st/common/cpu_time.hpp"  // processCpuSeconds

namespace st::app {

/// The CPU model from /proc/cpuinfo, or "unknown CPU".
std::string cpuModel();
/// The current UTC time as "YYYY-MM-DDThh:mm:ssZ".
std::string utcNow();

}  // namespace st::app

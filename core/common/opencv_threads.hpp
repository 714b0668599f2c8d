#pragma once

namespace st::detail {

/// OpenCV's own threads off (cv::setNumThreads(0)), once per process. Every OpenCV call in core runs on
/// small images inside parallelFor's bodies, where OpenCV's parallel backend (TBB on Debian) only adds a
/// second pool: its first use loaded TBB and its allocator with dlopen and started a worker per core in the
/// middle of the sky rate, ~80 ms on the 16-thread device machine (perf, H100, 2026-11-28).
void useOpenCvSequentially();

}  // namespace st::detail

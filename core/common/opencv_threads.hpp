#pragma once

namespace st::detail {

/// OpenCV's own threads off (cv::setNumThreads(0)), once per process. OpenCV works on single frames or
/// smaller in core, mostly inside parallelFor's bodies (the sky rate's connected components, the matched
/// filter's exclusion masks), where its parallel backend (TBB on Debian) only adds a second pool: its first
/// use there loaded TBB and its allocator with dlopen and started a worker per core in the middle of the sky
/// rate, ~80 ms on the 16-thread device machine (perf, H100, 2026-11-28). The one top-level call, the CPU
/// filter's filter2D of one frame's weights, runs on one thread now. Called at pre-processing's entry (before
/// any thread is inside OpenCV) and at each use (the entry points that do not pre-process).
void useOpenCvSequentially();

}  // namespace st::detail

#pragma once
// A cap on the threads of the parallelFor calls made on one thread (parallel.hpp), for work that runs beside
// the caller's own parallel loops: a side thread's loops on every core would start as many pool threads
// again (the pool grows for concurrent callers) and share the cores with the main loops (issue 16: the
// static sources' stacks made ahead on a thread of their own took 10 ms each instead of 3-4 ms, and the
// analysis waited for them).
namespace st {

/// While it lives, parallelFor on this thread uses at most `maxThreads` threads (this one among them; 1:
/// this one alone). Nested caps keep the smaller; the previous cap comes back at its end.
class ParallelThreadCap {
 public:
  explicit ParallelThreadCap(unsigned maxThreads) noexcept;
  ~ParallelThreadCap();
  ParallelThreadCap(const ParallelThreadCap&) = delete;
  ParallelThreadCap& operator=(const ParallelThreadCap&) = delete;

 private:
  unsigned m_previous;
};

}  // namespace st

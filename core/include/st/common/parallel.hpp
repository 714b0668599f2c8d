#pragma once
// A minimal parallel-for over an index range on std::threads. Work is handed out in chunks from an atomic
// counter; an exception thrown by any worker (st::Cancelled included) stops the others at their next chunk
// and is rethrown on the calling thread, so nothing escapes a thread (STYLE.md, "Catch at every boundary").
#include <cstddef>
#include <functional>

namespace st {

/// Number of worker threads parallelFor uses: ST_THREADS from the environment if set, else the hardware's.
unsigned workerCount();

/// Calls body(begin, end) on disjoint chunks [b, e) covering [0, n), `chunk` indices at a time, on up to
/// workerCount() threads (the calling thread is one of them). Blocks until all are done.
void parallelFor(std::size_t n, std::size_t chunk, const std::function<void(std::size_t, std::size_t)>& body);

/// As above on up to min(workerCount(), maxThreads) threads (0: workerCount()): a stage whose per-thread
/// buffers must fit a memory budget (the out-of-core tree search) runs on fewer threads.
void parallelFor(std::size_t n, std::size_t chunk, const std::function<void(std::size_t, std::size_t)>& body,
                 unsigned maxThreads);

}  // namespace st

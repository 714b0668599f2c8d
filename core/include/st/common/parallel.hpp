#pragma once
// A minimal parallel-for over an index range on std::threads kept in a pool between calls (a thread idle for
// a few seconds leaves). Work is handed out in chunks from an atomic counter; an exception thrown by any
// worker (st::Cancelled included) stops the others at their next chunk and is rethrown on the calling
// thread, so nothing escapes a thread (STYLE.md, "Catch at every boundary"). Calls may nest and may come
// from several threads at once; a body must not wait for another chunk of the same call (a chunk may run
// after another on the same thread).
#include <algorithm>
#include <cstddef>
#include <functional>
#include <vector>

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

/// std::sort(v.begin(), v.end(), less) on parallelFor's threads: parts sorted at once, then merged in pairs.
/// Where `less` is a total order (no two elements equivalent) the result is std::sort's exactly; otherwise
/// equivalent elements may come in another order (neither sort is stable).
template <class T, class Less>
void parallelSort(std::vector<T>& v, Less less) {
  constexpr std::size_t kMinPart = 4096;  // below this the threads cost more than they save
  unsigned parts = 1;
  while (parts * 2 <= workerCount() && v.size() / (parts * 2) >= kMinPart)
    parts *= 2;
  if (parts == 1) {
    std::sort(v.begin(), v.end(), less);
    return;
  }
  const auto at = [&](std::size_t part) {
    return v.begin() + static_cast<std::ptrdiff_t>(v.size() * part / parts);
  };
  parallelFor(parts, 1, [&](std::size_t p0, std::size_t p1) {
    for (std::size_t p = p0; p < p1; ++p)
      std::sort(at(p), at(p + 1), less);
  });
  for (std::size_t width = 1; width < parts; width *= 2) {
    parallelFor(parts / (2 * width), 1, [&](std::size_t m0, std::size_t m1) {
      for (std::size_t m = m0; m < m1; ++m)
        std::inplace_merge(at(2 * width * m), at(2 * width * m + width), at(2 * width * (m + 1)), less);
    });
  }
}

}  // namespace st

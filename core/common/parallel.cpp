#include "st/common/parallel.hpp"

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace st {

unsigned workerCount() {
  if (const char* env = std::getenv("ST_THREADS")) {
    const int n = std::atoi(env);
    if (n > 0) return static_cast<unsigned>(n);
  }
  return std::max(1u, std::thread::hardware_concurrency());
}

void parallelFor(std::size_t n, std::size_t chunk,
                 const std::function<void(std::size_t, std::size_t)>& body) {
  parallelFor(n, chunk, body, 0);
}

void parallelFor(std::size_t n, std::size_t chunk, const std::function<void(std::size_t, std::size_t)>& body,
                 unsigned maxThreads) {
  if (n == 0) return;
  chunk = std::max<std::size_t>(1, chunk);
  const std::size_t chunks = (n + chunk - 1) / chunk;
  const unsigned cap = maxThreads > 0 ? std::min(maxThreads, workerCount()) : workerCount();
  const unsigned threads = static_cast<unsigned>(std::min<std::size_t>(cap, chunks));
  if (threads <= 1) {
    for (std::size_t b = 0; b < n; b += chunk)
      body(b, std::min(n, b + chunk));
    return;
  }
  std::atomic<std::size_t> next{0};
  std::atomic<bool> failed{false};
  std::exception_ptr error;
  std::mutex errorMutex;
  auto worker = [&] {
    try {
      while (!failed.load(std::memory_order_relaxed)) {
        const std::size_t c = next.fetch_add(1, std::memory_order_relaxed);
        if (c >= chunks) break;
        const std::size_t b = c * chunk;
        body(b, std::min(n, b + chunk));
      }
    } catch (...) {
      std::lock_guard lock(errorMutex);
      if (!error) error = std::current_exception();
      failed.store(true);
    }
  };
  std::vector<std::thread> pool;
  pool.reserve(threads - 1);
  for (unsigned i = 1; i < threads; ++i)
    pool.emplace_back(worker);
  worker();
  for (auto& t : pool)
    t.join();
  if (error) std::rethrow_exception(error);
}

}  // namespace st

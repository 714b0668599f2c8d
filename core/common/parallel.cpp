#include "st/common/parallel.hpp"
#include "st/common/parallel_cap.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cerrno>
#include <cstdlib>
#include <deque>
#include <exception>
#include <map>
#include <mutex>
#include <thread>
#include <vector>

#ifdef __linux__
#include <sys/resource.h>
#endif

namespace st {
namespace {

// One parallelFor call: its chunks are claimed from `next` by the calling thread and by the pool threads
// that joined it.
struct Job {
  const std::function<void(std::size_t, std::size_t)>* body = nullptr;
  std::size_t n = 0, chunk = 1, chunks = 0;
  std::atomic<std::size_t> next{0};
  std::atomic<bool> failed{false};
  std::exception_ptr error;
  std::mutex errorMutex;
  unsigned tickets = 0;  ///< pool threads it may still take (guarded by the pool's mutex)
  unsigned active = 0;   ///< pool threads inside it now (guarded by the pool's mutex)
};

// Claims and runs chunks until none is left or one threw (the first exception is kept for the caller).
void runChunks(Job& job) {
  try {
    while (!job.failed.load(std::memory_order_relaxed)) {
      const std::size_t c = job.next.fetch_add(1, std::memory_order_relaxed);
      if (c >= job.chunks) break;
      const std::size_t b = c * job.chunk;
      (*job.body)(b, std::min(job.n, b + job.chunk));
    }
  } catch (...) {
    std::lock_guard lock(job.errorMutex);
    if (!job.error) job.error = std::current_exception();
    job.failed.store(true);
  }
}

// Threads kept between parallelFor calls. Starting and joining 15 threads per call cost the GPU pipeline
// ~1000 thread creations per run of the paper's problem (issue 16: clone3, stack mmap/munmap and the new
// threads' page faults on the main thread, ~0.1 s of the 16-thread host's wall time under perf). A thread
// idle for kIdleExit leaves (its thread_local buffers with it), so an idle GUI holds no workers.
// Deadlock-free with nested calls: a caller runs its own chunks and then waits only for the pool threads
// already inside its job, which run chunks they claimed and leave; a nested call whose helpers are busy
// elsewhere runs its chunks on its caller alone.
class Pool {
 public:
  void run(Job& job, unsigned helpers) {
    {
      std::lock_guard lock(m_mutex);
      job.tickets = helpers;
      m_queue.push_back(&job);
      if (m_idle < helpers) startThreads(helpers - m_idle);
    }
    m_work.notify_all();
    runChunks(job);
    std::unique_lock lock(m_mutex);
    // No chunk is left to claim: no pool thread may join any more, and those inside finish theirs.
    if (job.tickets > 0) m_queue.erase(std::find(m_queue.begin(), m_queue.end(), &job));
    m_left.wait(lock, [&] { return job.active == 0; });
  }

 private:
  static constexpr auto kIdleExit = std::chrono::seconds(5);

  // Enough threads for every caller at once, as when each call started its own (concurrent callers, e.g. a
  // device's host thread beside the pipeline, keep their threads), but nested calls (each of a call's
  // threads calling parallelFor again) are bounded. m_mutex held.
  void startThreads(unsigned count) {
    const unsigned most = 4 * std::max(1u, std::thread::hardware_concurrency());
    for (unsigned i = 0; i < count && m_threads < most; ++i) {
      try {
        std::thread([this] { work(); }).detach();
      } catch (...) {  // std::system_error, std::bad_alloc: the job is queued, so nothing may escape here
        return;        // no more threads to be had: the callers run their chunks themselves
      }
      ++m_threads;
      ++m_idle;  // counted idle from now on: it takes a job as soon as it runs
    }
  }

  void work() {
    std::unique_lock lock(m_mutex);
    for (;;) {
      if (!m_work.wait_for(lock, kIdleExit, [&] { return !m_queue.empty(); })) {
        --m_idle;
        --m_threads;
        return;
      }
      Job& job = *m_queue.front();
      if (--job.tickets == 0) m_queue.pop_front();
      ++job.active;
      --m_idle;
      lock.unlock();
      runChunks(job);
      lock.lock();
      ++m_idle;
      if (--job.active == 0) m_left.notify_all();
    }
  }

  std::mutex m_mutex;
  std::condition_variable m_work, m_left;
  std::deque<Job*> m_queue;  ///< jobs that still take pool threads, oldest first
  unsigned m_threads = 0;    ///< pool threads alive
  unsigned m_idle = 0;       ///< of which waiting for a job (or about to)
};

// The calling thread's nice value (Linux: per thread; 0 elsewhere).
int callerNice() {
#ifdef __linux__
  errno = 0;
  const int nice = getpriority(PRIO_PROCESS, 0);  // who = 0: this thread on Linux
  return errno == 0 ? nice : 0;
#else
  return 0;
#endif
}

// One pool per nice value of its callers: a new thread inherits its creator's nice value and an unprivileged
// thread cannot lower it again, so a job's helpers come from threads started by callers of its own priority
// (the GUI's job thread runs at nice +5, its scrubbing and the GUI thread at 0: they must not lend each other
// threads). Never destroyed: detached pool threads may still wait on their condition variables while the
// process exits.
Pool& poolFor(int nice) {
  static std::mutex mutex;
  static auto* const pools = new std::map<int, Pool*>;
  const std::lock_guard lock(mutex);
  Pool*& p = (*pools)[nice];
  if (!p) p = new Pool;
  return *p;
}

}  // namespace

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

namespace {
thread_local unsigned t_threadCap = 0;  // ParallelThreadCap's (0: none)
}  // namespace

ParallelThreadCap::ParallelThreadCap(unsigned maxThreads) noexcept : m_previous(t_threadCap) {
  const unsigned cap = std::max(1u, maxThreads);
  t_threadCap = m_previous > 0 ? std::min(m_previous, cap) : cap;
}

ParallelThreadCap::~ParallelThreadCap() {
  t_threadCap = m_previous;
}

void parallelFor(std::size_t n, std::size_t chunk, const std::function<void(std::size_t, std::size_t)>& body,
                 unsigned maxThreads) {
  if (n == 0) return;
  chunk = std::max<std::size_t>(1, chunk);
  const std::size_t chunks = (n + chunk - 1) / chunk;
  unsigned cap = maxThreads > 0 ? std::min(maxThreads, workerCount()) : workerCount();
  if (t_threadCap > 0) cap = std::min(cap, t_threadCap);
  const unsigned threads = static_cast<unsigned>(std::min<std::size_t>(cap, chunks));
  if (threads <= 1) {
    for (std::size_t b = 0; b < n; b += chunk)
      body(b, std::min(n, b + chunk));
    return;
  }
  Job job;
  job.body = &body;
  job.n = n;
  job.chunk = chunk;
  job.chunks = chunks;
  poolFor(callerNice()).run(job, threads - 1);
  if (job.error) std::rethrow_exception(job.error);
}

}  // namespace st

// HostCopies (host_copies.hpp): device -> host copies on a thread of their own, behind the stages after them.
#include "host_copies.hpp"

#include <algorithm>
#include <chrono>
#include <utility>

#include "cuda_preprocess.hpp"
#include "st/common/error.hpp"
#include "st/common/trace.hpp"

namespace st::gpu {

HostCopies::HostCopies(int device, std::string name) : m_device(device), m_name(std::move(name)) {}

HostCopies::~HostCopies() {
  drain();
  // m_thread (last) is stopped and joined first.
}

DeviceResources& HostCopies::resources() {
  std::call_once(m_made, [this] {
    ST_CUDA_CHECK(cudaSetDevice(m_device));
    auto r = std::make_unique<DeviceResources>();
    r->staging(0);
    r->staging(1);
    m_res = std::move(r);
  });
  return *m_res;
}

void HostCopies::enqueue(void* host, const void* dev, std::size_t bytes, cudaStream_t writer, bool inPlace,
                         std::string what, unsigned copyThreads, std::size_t chunkBytes) {
  if (bytes == 0) return;
  Piece p{host, dev, bytes, Event(), inPlace, std::move(what), copyThreads, chunkBytes};
  p.ready.record(writer);
  {
    const std::lock_guard lock(m_mutex);
    // The thread first: a piece is never queued without one to copy it (wait() would block for ever).
    if (!m_thread.joinable()) m_thread = std::jthread([this](std::stop_token stop) { run(stop); });
    m_queue.push_back(std::move(p));
  }
  m_changed.notify_all();
}

namespace {

/// Counts a blocked caller for its scope (HostCopies::m_waiters).
class Waiting {
 public:
  explicit Waiting(std::atomic<int>& waiters) : m_waiters(waiters) { m_waiters.fetch_add(1); }
  ~Waiting() { m_waiters.fetch_sub(1); }
  Waiting(const Waiting&) = delete;
  Waiting& operator=(const Waiting&) = delete;

 private:
  std::atomic<int>& m_waiters;
};

}  // namespace

std::exception_ptr HostCopies::wait() {
  const Waiting waiting(m_waiters);
  std::unique_lock lock(m_mutex);
  m_changed.wait(lock, [this] { return m_queue.empty() && !m_running; });
  return std::exchange(m_error, nullptr);
}

void HostCopies::drain() noexcept {
  const Waiting waiting(m_waiters);
  std::unique_lock lock(m_mutex);
  m_changed.wait(lock, [this] { return m_queue.empty() && !m_running; });
}

std::exception_ptr HostCopies::waitFor(const void* begin, const void* end) {
  const char* lo = static_cast<const char*>(begin);
  const char* hi = static_cast<const char*>(end);
  const auto writes = [lo, hi](const char* b, const char* e) { return b < hi && lo < e; };
  const auto pieceWrites = [&](const Piece& p) {
    const char* b = static_cast<const char*>(p.host);
    return writes(b, b + p.bytes);
  };
  const Waiting waiting(m_waiters);
  std::unique_lock lock(m_mutex);
  // Those pieces first, in their order, then the others in theirs (moved: a piece's event is not
  // assignable).
  if (std::any_of(m_queue.begin(), m_queue.end(), pieceWrites)) {
    std::deque<Piece> first, rest;
    for (Piece& p : m_queue)
      (pieceWrites(p) ? first : rest).push_back(std::move(p));
    for (Piece& p : rest)
      first.push_back(std::move(p));
    m_queue.swap(first);
  }
  m_changed.wait(lock, [&] {
    return std::none_of(m_queue.begin(), m_queue.end(), pieceWrites) &&
           !(m_running && writes(m_runningBegin, m_runningEnd));
  });
  return std::exchange(m_error, nullptr);
}

bool HostCopies::busy() const {
  const std::lock_guard lock(m_mutex);
  return !m_queue.empty() || m_running;
}

double HostCopies::copySeconds() const {
  const std::lock_guard lock(m_mutex);
  return m_seconds;
}

void HostCopies::run(std::stop_token stop) {
  std::unique_lock lock(m_mutex);
  for (;;) {
    if (!m_changed.wait(lock, stop, [this] { return !m_queue.empty(); })) return;  // stopped, nothing queued
    Piece p = std::move(m_queue.front());
    m_queue.pop_front();
    m_running = true;
    m_runningBegin = static_cast<const char*>(p.host);
    m_runningEnd = m_runningBegin + p.bytes;
    lock.unlock();
    const auto t0 = std::chrono::steady_clock::now();
    std::exception_ptr error;
    try {
      DeviceResources& r = resources();
      ST_CUDA_CHECK(cudaSetDevice(m_device));
      ST_CUDA_CHECK(cudaStreamWaitEvent(r.copy.get(), p.ready.get(), 0));
      preprocess_detail::download(r, p.host, p.dev, p.bytes, r.copy.get(), p.copyThreads, p.chunkBytes,
                                  &m_waiters);
    } catch (const GpuError& e) {
      error = std::current_exception();
      if (p.inPlace) {
        try {
          error = std::make_exception_ptr(
              Error(p.what + "'s download from " + m_name +
                    " failed part way, leaving the frames half written: " + e.what()));
        } catch (...) {  // no memory for the message: that (std::bad_alloc) stops the run as well
          error = std::current_exception();
        }
      }
    } catch (...) {
      error = std::current_exception();
    }
    const auto t1 = std::chrono::steady_clock::now();
    if (trace::enabled()) trace::record("copy: " + p.what, t0, t1);
    const double seconds = std::chrono::duration<double>(t1 - t0).count();
    lock.lock();
    m_seconds += seconds;
    if (error && !m_error) m_error = error;
    m_running = false;
    m_changed.notify_all();
  }
}

}  // namespace st::gpu

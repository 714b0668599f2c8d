#pragma once
// Device -> host copies that run behind the stages after them (issue 16): the zero-biased cube's download
// beside the noise model and the matched filter's kernels, and the filtered frames' download launch by launch
// beside the filter's later launches. The downloads were ~80 ms of the paper's pre-processing (1500 x
// 512^2, H200, 2026-12-02) with the device idle.
#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <exception>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "uploader.hpp"

namespace st::gpu {

/// One thread copies the queued pieces in their order, through its own stream and two pinned staging
/// buffers (a DeviceResources of its own, made by the first copy: no contention with the stages' staging
/// buffers; warmPreprocessStaging pins them ahead), each piece once
/// the work queued before it on the stream that writes its source is done. The host copy out of the
/// staging buffers runs on every core (parallelFor beside the caller's own loops).
class HostCopies {
 public:
  /// `device`: the ordinal the copies run on; `name`: the device's, for messages.
  HostCopies(int device, std::string name);
  /// Waits for the queued copies (their errors are dropped: the owner waited already where they mattered).
  ~HostCopies();
  HostCopies(const HostCopies&) = delete;
  HostCopies& operator=(const HostCopies&) = delete;

  /// Queues a copy of `bytes` from device memory `dev` to `host` after the work queued on `writer` so far.
  /// `inPlace`: `host` is the pipeline's own cube, which a failure part way leaves half written: wait()
  /// then throws st::Error (the run stops) instead of the GpuError (a CPU fallback writes a fresh
  /// destination anew). `what` names the data in messages. The caller keeps `dev` and `host` alive and
  /// unwritten until wait() or drain() returns (DrainOnExit for the exceptions on the way).
  /// `copyThreads` bounds the threads of its host copy (0: every core; a few for a download that runs behind
  /// host stages, which would lose their cores to it); `chunkBytes` each DMA's size
  /// (preprocess_detail::download).
  void enqueue(void* host, const void* dev, std::size_t bytes, cudaStream_t writer, bool inPlace,
               std::string what, unsigned copyThreads = 0, std::size_t chunkBytes = 0);
  /// Blocks until every queued copy is done; the first failure since the last wait() is returned (and
  /// forgotten), null when none.
  [[nodiscard]] std::exception_ptr wait();
  /// Blocks until every queued copy is done, keeping a failure for the next wait(). Never throws.
  void drain() noexcept;
  /// True while a copy is queued or running.
  [[nodiscard]] bool busy() const;
  /// Blocks until no queued or running copy writes host bytes in [begin, end): the queued pieces that do
  /// are moved to the front of the queue first (in their order), so a stage that needs a few frames of a
  /// cube still downloading waits for those, not for the whole cube. The first failure since the last
  /// wait() is returned (and forgotten), null when none.
  [[nodiscard]] std::exception_ptr waitFor(const void* begin, const void* end);

  /// drain() when it goes out of scope: declared after the buffers the copies read or write, it keeps them
  /// alive until the copies are done, also while an exception unwinds the scope.
  class DrainOnExit {
   public:
    explicit DrainOnExit(HostCopies& copies) noexcept : m_copies(copies) {}
    ~DrainOnExit() { m_copies.drain(); }
    DrainOnExit(const DrainOnExit&) = delete;
    DrainOnExit& operator=(const DrainOnExit&) = delete;

   private:
    HostCopies& m_copies;
  };
  /// drain() when it goes out of scope because an exception unwinds it (not on a normal exit, where the
  /// copies run on behind the caller): declared after a buffer that queued copies read, it keeps that buffer
  /// alive until they are done.
  class DrainOnError {
   public:
    explicit DrainOnError(HostCopies& copies) noexcept
        : m_copies(copies), m_uncaught(std::uncaught_exceptions()) {}
    ~DrainOnError() {
      if (std::uncaught_exceptions() > m_uncaught) m_copies.drain();
    }
    DrainOnError(const DrainOnError&) = delete;
    DrainOnError& operator=(const DrainOnError&) = delete;

   private:
    HostCopies& m_copies;
    int m_uncaught;
  };
  /// Seconds spent copying since construction (for the stages' notes: the difference over a stage).
  [[nodiscard]] double copySeconds() const;

 private:
  struct Piece {
    void* host;
    const void* dev;
    std::size_t bytes;
    Event ready;
    bool inPlace;
    std::string what;
    unsigned copyThreads;
    std::size_t chunkBytes;  ///< each DMA's size (0: a staging buffer's)
  };
  void run(std::stop_token stop);
  DeviceResources& resources();

  int m_device;
  std::string m_name;
  std::once_flag m_made;
  std::unique_ptr<DeviceResources> m_res;  // made by the first copy, with m_device current
  mutable std::mutex m_mutex;
  std::condition_variable_any m_changed;
  std::deque<Piece> m_queue;
  bool m_running = false;                ///< the thread is copying a piece taken off the queue
  const char* m_runningBegin = nullptr;  ///< the host bytes that piece writes
  const char* m_runningEnd = nullptr;
  std::exception_ptr m_error;
  double m_seconds = 0.0;
  /// Callers blocked in wait(), drain() or waitFor(): while there is one, the host copies run on every core
  /// whatever their copyThreads (their cap keeps the cores for the stages beside them; a waiting stage has
  /// none running).
  std::atomic<int> m_waiters{0};
  std::jthread m_thread;  // last: stopped and joined before the members it reads are destroyed
};

}  // namespace st::gpu

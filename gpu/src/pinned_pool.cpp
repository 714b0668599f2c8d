// Pinned staging buffers made ahead (uploader.hpp: warmPinnedStaging, takePinnedStaging).
#include <algorithm>
#include <mutex>
#include <vector>

#include "st/gpu/preprocess.hpp"
#include "uploader.hpp"

namespace st::gpu {
namespace {

struct Pool {
  std::mutex mutex;
  std::vector<PinnedBuffer> buffers;
};

// Never destroyed: freeing pinned memory while the CUDA runtime unloads at exit fails, and the process is
// ending anyway.
Pool& pool() {
  static Pool* p = new Pool;
  return *p;
}

}  // namespace

void warmPinnedStaging(int count) {
  // Topped up to `count`, not added to: a GUI makes a backend for every job.
  std::size_t missing = 0;
  {
    const std::lock_guard lock(pool().mutex);
    const std::size_t want = static_cast<std::size_t>(std::max(0, count));
    missing = want > pool().buffers.size() ? want - pool().buffers.size() : 0;
  }
  for (std::size_t k = 0; k < missing; ++k) {
    PinnedBuffer b(kStagingBytes);  // outside the lock: ~15-35 ms each
    const std::lock_guard lock(pool().mutex);
    pool().buffers.push_back(std::move(b));
  }
}

void warmPreprocessStaging() noexcept {
  try {
    // Two for the stages' uploads and downloads, two for the downloads behind them (HostCopies). Pinned on
    // the accelerator's own threads instead, they slowed the frame backgrounds' upload beside them from
    // 35-56 ms to 64-101 ms (H200, 2026-12-02 06:20 UTC).
    warmPinnedStaging(4);
  } catch (...) {
    // The accelerator pins its own.
  }
}

PinnedBuffer takePinnedStaging() {
  {
    const std::lock_guard lock(pool().mutex);
    if (!pool().buffers.empty()) {
      PinnedBuffer b = std::move(pool().buffers.back());
      pool().buffers.pop_back();
      return b;
    }
  }
  return PinnedBuffer(kStagingBytes);
}

}  // namespace st::gpu

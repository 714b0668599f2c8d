// Pinned staging buffers made ahead (uploader.hpp: warmPinnedStaging, takePinnedStaging).
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
  for (int k = 0; k < count; ++k) {
    PinnedBuffer b(kStagingBytes);  // outside the lock: ~15-35 ms each
    const std::lock_guard lock(pool().mutex);
    pool().buffers.push_back(std::move(b));
  }
}

void warmPreprocessStaging() noexcept {
  try {
    warmPinnedStaging(2);
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

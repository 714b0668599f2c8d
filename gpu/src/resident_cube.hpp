#pragma once
// One resident filtered cube per device (issue 16): the matched filter on the device leaves its output
// here, and the exact search, the tree search and stackAt use it without an upload while the host cube is
// the same one (cubeKey: buffer address, sizes, frame times, 4096 sampled pixels). A search of another
// cube frees it first. Each slot is locked by whoever uses it (one device thread of a search, stackAt, the
// pre-processing) for the whole use.
#include <cstdint>
#include <mutex>

#include "cuda_check.hpp"
#include "st/common/frame_cube.hpp"
#include "st/search/types.hpp"

namespace st::gpu {

struct ResidentSlot {
  std::mutex mutex;
  DeviceBuffer<float> cube;  ///< on the slot's device
  std::uint64_t key = 0;     ///< cubeKey of the host cube it holds; 0 = none (or an upload in progress)
  /// Whether the slot holds `key`'s cube of `floats` floats.
  [[nodiscard]] bool holds(std::uint64_t k, std::size_t floats) const {
    return k != 0 && key == k && cube.size() == floats;
  }
  /// Frees the cube (the slot's device must be current).
  void clear() {
    key = 0;
    cube = DeviceBuffer<float>();
  }
  /// Times the search found the cube resident / uploaded it (for notes and tests).
  int reused = 0;
  int uploads = 0;
};

/// The slot of device `ordinal` (process-wide).
ResidentSlot& residentSlot(int ordinal);

/// Identity of a host cube's layout and a sample of its pixels (never 0): buffer address, sizes, frame times,
/// 4096 sampled pixels. Not proof of equal pixels on its own (a new cube of the same noise in a reused
/// buffer can match it), hence residentKey.
std::uint64_t cubeKey(const FrameCube& frames);
/// cubeKey without the pixels (buffer address, sizes, frame times): for a cube whose pixels a download may be
/// writing.
std::uint64_t cubeShapeKey(const FrameCube& frames);

/// The key under which a search keeps and finds `cube` on a device: cubeKey mixed with
/// FilteredCube::revision; 0 (never resident) when the cube has no revision.
std::uint64_t residentKey(const FrameCube& frames, std::uint64_t revision);

/// Frees the resident cube of every device in [devices, devices + count) that does not hold `key`.
void releaseOtherCubes(const int* devices, int count, std::uint64_t key);

}  // namespace st::gpu

#include "resident_cube.hpp"

#include <algorithm>
#include <array>
#include <cstring>

namespace st::gpu {
namespace {

std::uint64_t mix(std::uint64_t h, std::uint64_t v) {
  h ^= v + 0x9E3779B97F4A7C15ull + (h << 6) + (h >> 2);
  return h;
}

}  // namespace

ResidentSlot& residentSlot(int ordinal) {
  static std::array<ResidentSlot, 64> slots;
  if (ordinal < 0 || ordinal >= static_cast<int>(slots.size()))
    throw GpuError("device ordinal " + std::to_string(ordinal) + " out of range");
  return slots[static_cast<std::size_t>(ordinal)];
}

namespace {

// cubeKey's part before the pixels (unclamped).
std::uint64_t shapeMix(const FrameCube& f) {
  std::uint64_t h = mix(0, reinterpret_cast<std::uintptr_t>(f.pixels().data()));
  h = mix(h, f.pixels().size());
  h = mix(h, static_cast<std::uint64_t>(f.width()) << 32 | static_cast<std::uint32_t>(f.height()));
  for (const auto& info : f.info()) {
    std::uint64_t bits = 0;
    std::memcpy(&bits, &info.mjdMid, sizeof(bits));
    h = mix(h, bits);
  }
  return h;
}

}  // namespace

std::uint64_t cubeShapeKey(const FrameCube& f) {
  const std::uint64_t h = shapeMix(f);
  return h == 0 ? 1 : h;
}

std::uint64_t cubeKey(const FrameCube& f) {
  std::uint64_t h = shapeMix(f);
  const std::size_t n = f.pixels().size();
  const std::size_t step = std::max<std::size_t>(1, n / 4096);
  for (std::size_t i = 0; i < n; i += step) {
    std::uint32_t bits = 0;
    std::memcpy(&bits, &f.pixels()[i], sizeof(bits));
    h = mix(h, bits);
  }
  return h == 0 ? 1 : h;
}

std::uint64_t residentKey(const FrameCube& frames, std::uint64_t revision) {
  if (revision == 0) return 0;
  const std::uint64_t h = mix(cubeKey(frames), revision);
  return h == 0 ? 1 : h;
}

void releaseOtherCubes(const int* devices, int count, std::uint64_t key) {
  for (int d = 0; d < count; ++d) {
    ResidentSlot& slot = residentSlot(devices[d]);
    std::lock_guard lock(slot.mutex);
    if (slot.key == key && slot.cube.size() > 0) continue;
    if (slot.cube.size() == 0) continue;
    ST_CUDA_CHECK(cudaSetDevice(devices[d]));
    slot.clear();
  }
}

}  // namespace st::gpu

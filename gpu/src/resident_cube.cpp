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

CubeKeyShape cubeKeyShape(const FrameCube& f) {
  CubeKeyShape k{f.pixels().data(), f.pixels().size(), f.width(), f.height(), {}};
  k.mjdMid.reserve(f.info().size());
  for (const auto& info : f.info())
    k.mjdMid.push_back(info.mjdMid);
  return k;
}

std::uint64_t cubeKey(const CubeKeyShape& k) {
  std::uint64_t h = mix(0, reinterpret_cast<std::uintptr_t>(k.pixels));
  h = mix(h, k.size);
  h = mix(h, static_cast<std::uint64_t>(k.width) << 32 | static_cast<std::uint32_t>(k.height));
  for (double mjd : k.mjdMid) {
    std::uint64_t bits = 0;
    std::memcpy(&bits, &mjd, sizeof(bits));
    h = mix(h, bits);
  }
  const std::size_t step = std::max<std::size_t>(1, k.size / 4096);
  for (std::size_t i = 0; i < k.size; i += step) {
    std::uint32_t bits = 0;
    std::memcpy(&bits, &k.pixels[i], sizeof(bits));
    h = mix(h, bits);
  }
  return h == 0 ? 1 : h;
}

std::uint64_t cubeKey(const FrameCube& f) {
  return cubeKey(cubeKeyShape(f));
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

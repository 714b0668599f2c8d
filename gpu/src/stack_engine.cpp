#include "stack_engine.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <vector>

#include "kernel_params.hpp"
#include "st/common/error.hpp"

namespace st::gpu {
namespace {

constexpr int kStackGroups = 16;

std::uint64_t mix(std::uint64_t h, std::uint64_t v) {
  h ^= v + 0x9E3779B97F4A7C15ull + (h << 6) + (h >> 2);
  return h;
}

/// Identity of a cube: buffer address, sizes, frame times and 4096 sampled pixels.
std::uint64_t cubeKey(const FrameCube& f) {
  std::uint64_t h = mix(0, reinterpret_cast<std::uintptr_t>(f.pixels().data()));
  h = mix(h, f.pixels().size());
  h = mix(h, static_cast<std::uint64_t>(f.width()) << 32 | static_cast<std::uint32_t>(f.height()));
  for (const auto& info : f.info()) {
    std::uint64_t bits = 0;
    std::memcpy(&bits, &info.mjdMid, sizeof(bits));
    h = mix(h, bits);
  }
  const std::size_t n = f.pixels().size();
  const std::size_t step = std::max<std::size_t>(1, n / 4096);
  for (std::size_t i = 0; i < n; i += step) {
    std::uint32_t bits = 0;
    std::memcpy(&bits, &f.pixels()[i], sizeof(bits));
    h = mix(h, bits);
  }
  return h;
}

}  // namespace

void StackEngine::ensureResident(const FrameCube& frames) {
  const std::uint64_t key = cubeKey(frames);
  if (key == m_key && m_cube.size() == frames.pixels().size()) return;
  m_key = 0;
  m_cube = DeviceBuffer<float>();  // free the old cube before taking the new one
  m_cube = DeviceBuffer<float>(frames.pixels().size());
  ST_CUDA_CHECK(cudaMemcpy(m_cube.get(), frames.pixels().data(), m_cube.bytes(), cudaMemcpyHostToDevice));
  m_partial = DeviceBuffer<float>(static_cast<std::size_t>(kStackGroups) * frames.framePixels());
  m_out = DeviceBuffer<float>(frames.framePixels());
  m_shifts = DeviceBuffer<int>(2 * frames.frameCount());
  m_key = key;
}

Image StackEngine::stack(const search::FilteredCube& cube, Velocity v) {
  const FrameCube& f = cube.frames;
  if (f.frameCount() == 0) throw InputError("cannot stack a cube with no frames");
  if (f.pixels().size() != f.frameCount() * f.framePixels()) {
    throw InputError("the cube's pixel buffer does not match its frames");
  }
  ST_CUDA_CHECK(cudaSetDevice(m_device));
  ensureResident(f);
  const std::vector<double> dt = f.timeOffsetsS();
  const std::size_t n = dt.size();
  std::vector<int> shifts(2 * n);
  for (std::size_t k = 0; k < n; ++k) {
    shifts[k] = static_cast<int>(std::lround(f.info()[k].offsetXPx + v.vx * dt[k]));
    shifts[n + k] = static_cast<int>(std::lround(f.info()[k].offsetYPx + v.vy * dt[k]));
  }
  ST_CUDA_CHECK(
      cudaMemcpy(m_shifts.get(), shifts.data(), shifts.size() * sizeof(int), cudaMemcpyHostToDevice));
  StackLaunch p{};
  p.frames = m_cube.get();
  p.width = f.width();
  p.height = f.height();
  p.frameCount = static_cast<int>(n);
  p.shiftX = m_shifts.get();
  p.shiftY = m_shifts.get() + n;
  p.groups = static_cast<int>(std::min<std::size_t>(kStackGroups, n));
  p.partial = m_partial.get();
  p.out = m_out.get();
  Event start(true);
  Event stop(true);
  start.record(nullptr);
  launchStack(p, nullptr);
  stop.record(nullptr);
  Image out(f.width(), f.height());
  ST_CUDA_CHECK(cudaMemcpy(out.data(), m_out.get(), m_out.bytes(), cudaMemcpyDeviceToHost));
  float ms = 0.0f;
  ST_CUDA_CHECK(cudaEventElapsedTime(&ms, start.get(), stop.get()));
  m_lastSeconds = ms * 1e-3;
  return out;
}

}  // namespace st::gpu

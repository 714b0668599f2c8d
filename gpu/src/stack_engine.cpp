#include "stack_engine.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <mutex>
#include <vector>

#include "kernel_params.hpp"
#include "resident_cube.hpp"
#include "st/common/error.hpp"

namespace st::gpu {
namespace {

constexpr int kStackGroups = 16;

}  // namespace

const float* StackEngine::ensureResident(const search::FilteredCube& cube, ResidentSlot& slot) {
  const FrameCube& frames = cube.frames;
  // A cube with a revision is the searches' (resident_cube.hpp); without one, its sampled key (as before).
  const std::uint64_t key = cube.revision != 0 ? residentKey(frames, cube.revision) : cubeKey(frames);
  if (!slot.holds(key, frames.pixels().size())) {
    slot.clear();  // free the old cube before taking the new one
    slot.cube = DeviceBuffer<float>(frames.pixels().size());
    ST_CUDA_CHECK(
        cudaMemcpy(slot.cube.get(), frames.pixels().data(), slot.cube.bytes(), cudaMemcpyHostToDevice));
    slot.key = key;
    ++slot.uploads;
  } else {
    ++slot.reused;
  }
  if (m_out.size() != frames.framePixels() || m_shifts.size() != 2 * frames.frameCount()) {
    m_partial = DeviceBuffer<float>(static_cast<std::size_t>(kStackGroups) * frames.framePixels());
    m_out = DeviceBuffer<float>(frames.framePixels());
    m_shifts = DeviceBuffer<int>(2 * frames.frameCount());
  }
  return slot.cube.get();
}

Image StackEngine::stack(const search::FilteredCube& cube, Velocity v) {
  const FrameCube& f = cube.frames;
  if (f.frameCount() == 0) throw InputError("cannot stack a cube with no frames");
  if (f.pixels().size() != f.frameCount() * f.framePixels()) {
    throw InputError("the cube's pixel buffer does not match its frames");
  }
  ST_CUDA_CHECK(cudaSetDevice(m_device));
  ResidentSlot& slot = residentSlot(m_device);
  std::lock_guard lock(slot.mutex);
  const float* frames = ensureResident(cube, slot);
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
  p.frames = frames;
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

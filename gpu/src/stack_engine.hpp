#pragma once
// stackAt on the GPU for live scrubbing: the cube is uploaded once to device 0 and kept while the same
// cube is stacked again (identified by its buffer address, sizes, times and a sample of its pixels).
#include <cstdint>

#include "cuda_check.hpp"
#include "st/search/types.hpp"

namespace st::gpu {

class StackEngine {
 public:
  explicit StackEngine(int device) : m_device(device) {}
  /// IPSA stack: sum over frames of F_n(x + round(vx dt_n), y + round(vy dt_n)), out-of-frame samples
  /// excluded (as st::search::SearchBackend::stackAt). Throws st::GpuError.
  Image stack(const search::FilteredCube& cube, Velocity v);
  /// Device seconds of the last stack's kernels.
  [[nodiscard]] double lastKernelSeconds() const noexcept { return m_lastSeconds; }

 private:
  void ensureResident(const FrameCube& frames);
  int m_device;
  std::uint64_t m_key = 0;
  DeviceBuffer<float> m_cube;
  DeviceBuffer<float> m_partial;
  DeviceBuffer<float> m_out;
  DeviceBuffer<int> m_shifts;
  double m_lastSeconds = 0.0;
};

}  // namespace st::gpu

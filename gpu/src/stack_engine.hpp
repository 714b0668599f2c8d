#pragma once
// stackAt on the GPU for live scrubbing: the cube is the device's resident cube (resident_cube.hpp, shared
// with the searches and the GPU matched filter), uploaded only when it holds another cube.
#include <cstdint>

#include "cuda_check.hpp"
#include "resident_cube.hpp"
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
  /// The cube on the device: the device's resident cube (resident_cube.hpp) when it holds this one, else
  /// uploaded into it.
  const float* ensureResident(const search::FilteredCube& cube, ResidentSlot& slot);
  int m_device;
  DeviceBuffer<float> m_partial;
  DeviceBuffer<float> m_out;
  DeviceBuffer<int> m_shifts;
  double m_lastSeconds = 0.0;
};

}  // namespace st::gpu

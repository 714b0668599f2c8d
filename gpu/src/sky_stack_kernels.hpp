#pragma once
// detect::stackAtSkyRate on a cube already on the device (issue 16: the stacks the static-source search and
// the PSF stage ask for, made from the prefetched calibrated cube).
#include <cuda_runtime.h>

#include <cstdint>

namespace st::gpu {

struct SkyStackLaunch {
  const float* pix = nullptr;          ///< nf frames of width x height, frame-major
  const std::uint8_t* mask = nullptr;  ///< the cube's mask, or null
  int width = 0, height = 0;
  const int* shiftX = nullptr;  ///< MovingMask::shiftX(n), per frame of the cube
  const int* shiftY = nullptr;
  int first = 0, last = 0;  ///< frames [first, last)
  int x0 = 0, y0 = 0;       ///< the canvas origin (MovingMask::x0, y0)
  int cw = 0, ch = 0;       ///< the canvas
  double subtract = 0.0;
  float* mean = nullptr;  ///< cw x ch outputs (SkyStack::mean, count, max)
  float* count = nullptr;
  float* max = nullptr;
};

/// One thread per canvas pixel, its frames in order: the CPU's double sums in its order (no multiply, so
/// nothing to contract: equal stacks), count and maximum as std::max.
void launchSkyStack(const SkyStackLaunch& p, cudaStream_t s);

}  // namespace st::gpu

#pragma once
// The stages between the per-pixel background and the residual means on a cube kept on the device (issue
// 16): detect::subtractStarTemplate and the zeroing stages, host side (the CPU's tables made as core makes
// them; kernels in zero_bias_kernels.cu). Each throws st::GpuError on a CUDA failure.
#include <cuda_runtime.h>

#include <cstdint>
#include <string>
#include <vector>

#include "st/common/frame_cube.hpp"
#include "st/detect/star_subtraction.hpp"
#include "st/detect/static_sources.hpp"

namespace st::gpu {

/// A cube on the current device: nf frames of width x height (frame-major), its mask (or null).
struct DeviceCubeRef {
  float* pix = nullptr;
  const std::uint8_t* mask = nullptr;
  int width = 0, height = 0, nf = 0;
};

/// detect::subtractStarTemplate(cube, region, sigma, params) on `d` (cube: the host cube's times, offsets
/// and size; its pixels are not read). `sigma`: the per-pixel background sigma on the device, or null.
/// Templates and subtracted pixels are the CPU's (same arithmetic); the residual variance per position
/// within the rounding of its double sums.
detect::StarSubtraction subtractStarTemplateOnDevice(const FrameCube& cube, DeviceCubeRef d,
                                                     const MovingMask& region, const float* sigma,
                                                     const detect::StarSubtractionParams& params,
                                                     cudaStream_t s, std::string* timing = nullptr);

/// calib::zeroPixels.
void zeroPixelsOnDevice(DeviceCubeRef d, const std::vector<std::uint64_t>& pixels, cudaStream_t s);

/// detect::zeroMasked.
std::size_t zeroMaskedOnDevice(DeviceCubeRef d, const MovingMask& mask, cudaStream_t s);

/// detect::zeroUnmeasured.
std::size_t zeroUnmeasuredOnDevice(DeviceCubeRef d, const std::vector<std::uint8_t>& unmeasured,
                                   const MovingMask& keep, cudaStream_t s);

/// detect::zeroSingleFrameSources; `sigma`: the per-pixel noise image on the device, or null (sigmaN).
detect::SingleFrameSources zeroSingleFrameSourcesOnDevice(DeviceCubeRef d, const float* sigma, double sigmaN,
                                                          double snr, int radiusPx, const MovingMask* keep,
                                                          cudaStream_t s);

}  // namespace st::gpu

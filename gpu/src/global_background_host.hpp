#pragma once
// stats::globalBackground of a cube that is already on the device (global_background.hpp).
#include <cuda_runtime.h>

#include <cstdint>

#include "st/common/frame_cube.hpp"
#include "st/stats/background.hpp"

namespace st::gpu {

/// stats::globalBackground(cube, params) computed from `pix` (the same cube on the device, frame-major) and
/// `mask` (its mask on the device, or null): the same samples, the same clip and convergence rule; mean and
/// sigma within the rounding of the CPU's sequential double sums (tests: 1e-12 relative), count and
/// iterations equal. `cube` is read for its mask, shape and the error message only (the clip's shift, the
/// first sample, is read from `pix`: the host pixels may still be downloading).
/// Throws st::InputError when every sample is masked (as the CPU), st::GpuError on a CUDA failure.
stats::ClipStats globalBackgroundOnDevice(const FrameCube& cube, const float* pix, const std::uint8_t* mask,
                                          const stats::GlobalBackgroundParams& params, cudaStream_t stream);

/// The same for a cube on the host: only the frames the clip uses (50 of them by default, 52 MB for 512^2
/// frames) are uploaded.
stats::ClipStats globalBackgroundUploaded(const FrameCube& cube, const stats::GlobalBackgroundParams& params,
                                          cudaStream_t stream);

}  // namespace st::gpu

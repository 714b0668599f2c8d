#pragma once
// stats::removeResidualMeans of a cube already on the device (residual_means.hpp).
#include <cuda_runtime.h>

namespace st::gpu {

/// stats::removeResidualMeans(cube, meshPx, clipSigma) on `pix` (nf frames of width x height on the current
/// device, written in place); returns the rms of the cell means. Cell means within the rounding of the CPU's
/// double sums (the same samples, start, clip passes); the subtraction in the CPU's arithmetic. Throws
/// st::GpuError on a CUDA failure.
double removeResidualMeansOnDevice(float* pix, int width, int height, int nf, int meshPx, double clipSigma,
                                   cudaStream_t stream);

}  // namespace st::gpu

#pragma once
// stats::removeResidualMeans of a cube already on the device (residual_means.hpp).
#include <cuda_runtime.h>

#include <cstddef>
#include <functional>

namespace st::gpu {

/// stats::removeResidualMeans(cube, meshPx, clipSigma) on `pix` (nf frames of width x height on the current
/// device, written in place); returns the rms of the cell means. Cell means within the rounding of the CPU's
/// double sums (the same samples, start, clip passes); the subtraction in the CPU's arithmetic. Throws
/// st::GpuError on a CUDA failure. With `framesPerChunk` > 0, chunk by chunk of frames (the same values),
/// chunkDone(f0, f1) called once frames [f0, f1)'s subtraction is queued on `stream` (a download of them may
/// be queued behind it while the next chunks are made).
/// With `pinned` (page-locked host memory of `pinnedBytes`, e.g. a staging buffer, unused by anything else
/// until this returns) large enough for two chunks' means, the chunks are pipelined: the next chunk's cell
/// means run on the device while the host fills this chunk's (the same values; ST_GPU_RESIDUAL_MEANS_SERIAL=1
/// makes them one after the other, as before 2026-12-03).
double removeResidualMeansOnDevice(float* pix, int width, int height, int nf, int meshPx, double clipSigma,
                                   cudaStream_t stream, int framesPerChunk = 0,
                                   const std::function<void(int, int)>& chunkDone = {},
                                   void* pinned = nullptr, std::size_t pinnedBytes = 0);

}  // namespace st::gpu

#pragma once
// Device helpers shared by the search kernels (C++17, CUDA only): map keys, warp reductions, N_in from
// frame spans, cell scoring and candidate append, cp.async copies.
#include <cuda_runtime.h>

#include "kernel_params.hpp"

namespace st::gpu {

/// The bits of `snr` as an unsigned number in the float's order (the high word of packKey).
__device__ __forceinline__ unsigned orderedBits(float snr) {
  const unsigned int bits = __float_as_uint(snr);
  return (bits & 0x80000000u) ? ~bits : (bits | 0x80000000u);
}

__device__ __forceinline__ unsigned long long packKey(float snr, int pixel) {
  return (static_cast<unsigned long long>(orderedBits(snr)) << 32) |
         (0xFFFFFFFFull - static_cast<unsigned int>(pixel));
}

__device__ __forceinline__ unsigned long long warpMax(unsigned long long v) {
  for (int o = 16; o > 0; o >>= 1) {
    const unsigned long long other = __shfl_xor_sync(0xFFFFFFFFu, v, o);
    v = other > v ? other : v;
  }
  return v;
}

__device__ __forceinline__ int framesInBoth(int2 a, int2 b) {
  const int lo = max(a.x, b.x);
  const int hi = min(a.y, b.y);
  return hi >= lo ? hi - lo + 1 : 0;
}

/// N_in of cell (x, y) at velocity (ix, iy) for registered frames: the frames that keep both the column and
/// the row in frame (search::countFramesInRow on the CPU).
__device__ __forceinline__ int framesInMasks(const unsigned* maskX, const unsigned* maskY, int words, int ix,
                                             int x, int width, int iy, int y, int height) {
  const unsigned* a = maskX + (static_cast<long long>(ix) * width + x) * words;
  const unsigned* b = maskY + (static_cast<long long>(iy) * height + y) * words;
  int n = 0;
  for (int w = 0; w < words; ++w)
    n += __popc(__ldg(a + w) & __ldg(b + w));
  return n;
}

/// N_in of a cell: from the masks when the frames are registered, else from the frame spans.
__device__ __forceinline__ int cellFrames(const SearchLaunch& p, int ix, int x, int iy, int y) {
  if (p.maskX) return framesInMasks(p.maskX, p.maskY, p.maskWords, ix, x, p.width, iy, y, p.height);
  return framesInBoth(p.spanX[static_cast<long long>(ix) * p.width + x],
                      p.spanY[static_cast<long long>(iy) * p.height + y]);
}

/// Scores one cell; returns its map key (0 when the cell is ignored) and appends it when above threshold.
__device__ __forceinline__ unsigned long long scoreCell(const SearchLaunch& p, float sum, int nIn, int x,
                                                        int y, int ix, int iy) {
  if (nIn <= 0 || nIn < p.minFrames) return 0ull;
  const float snr = sum * p.invNorm[nIn];
  if (snr > p.snrThreshold) {
    const unsigned long long slot = atomicAdd(p.cellCount, 1ull);
    if (slot < p.cellCapacity) p.cells[slot] = DeviceCell{x, y, ix, iy, sum, snr, nIn, 0};
  }
  return packKey(snr, y * p.width + x);
}

/// One cell at the end of a launch: stores `sum` at partial[partialIndex] when this is not the last frame
/// chunk (returns 0), else scores it with N_in from the frame spans and returns its map key (scoreCell).
__device__ __forceinline__ unsigned long long finishCell(const SearchLaunch& p, float sum,
                                                         long long partialIndex, int x, int y, int ix,
                                                         int iy) {
  if (!p.finalize) {
    p.partial[partialIndex] = sum;
    return 0ull;
  }
  const int nIn = cellFrames(p, ix, x, iy, y);
  return scoreCell(p, sum, nIn, x, y, ix, iy);
}

__device__ __forceinline__ void cpAsync4(float* dst, const float* src, bool inFrame) {
  const unsigned int d = static_cast<unsigned int>(__cvta_generic_to_shared(dst));
  const int srcBytes = inFrame ? 4 : 0;  // 0 bytes read: the 4 destination bytes are zero-filled
  asm volatile("cp.async.ca.shared.global [%0], [%1], 4, %2;\n" ::"r"(d), "l"(src), "r"(srcBytes));
}
__device__ __forceinline__ void cpAsync16(float* dst, const float* src, bool inFrame) {
  const unsigned int d = static_cast<unsigned int>(__cvta_generic_to_shared(dst));
  const int srcBytes = inFrame ? 16 : 0;
  asm volatile("cp.async.cg.shared.global [%0], [%1], 16, %2;\n" ::"r"(d), "l"(src), "r"(srcBytes));
}
__device__ __forceinline__ void cpAsyncCommit() {
  asm volatile("cp.async.commit_group;\n" ::);
}
__device__ __forceinline__ void cpAsyncWaitOne() {
  asm volatile("cp.async.wait_group 1;\n" ::);
}

}  // namespace st::gpu

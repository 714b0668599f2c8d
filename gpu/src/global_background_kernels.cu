// The global background's clip (stats::globalBackground) on a cube already on the device: one pass of the
// clip's moments (count, sum and sum of squares of y - shift over the samples <= hi) per launch, reduced in
// a fixed order (per thread in index order, then a fixed tree per block; the host adds the blocks in order),
// so the result does not change from run to run; it differs from the CPU's sequential double sums only by
// their rounding (~1e-15 relative).
#include <cmath>
#include <cstdint>

#include "cuda_check.hpp"
#include "global_background.hpp"

namespace st::gpu {
namespace {

__global__ void globalMomentsKernel(GlobalMomentsLaunch p) {
  __shared__ double sS[kGlobalMomentThreads], sSS[kGlobalMomentThreads];
  __shared__ unsigned long long sC[kGlobalMomentThreads];
  const std::size_t total = static_cast<std::size_t>(p.nFrames) * p.framePixels;
  double s = 0.0, ss = 0.0;
  unsigned long long c = 0;
  for (std::size_t idx = blockIdx.x * static_cast<std::size_t>(blockDim.x) + threadIdx.x; idx < total;
       idx += static_cast<std::size_t>(gridDim.x) * blockDim.x) {
    const std::size_t k = idx / p.framePixels, i = idx - k * p.framePixels;
    const std::size_t off = static_cast<std::size_t>(p.frames[k]) * p.framePixels + i;
    const float v = p.pix[off];
    if ((p.mask && p.mask[off]) || !isfinite(v)) continue;
    const double y = v;
    if (y > p.hi) continue;
    const double d = __dsub_rn(y, p.shift);
    ++c;
    s = __dadd_rn(s, d);
    ss = __dadd_rn(ss, __dmul_rn(d, d));
  }
  sS[threadIdx.x] = s;
  sSS[threadIdx.x] = ss;
  sC[threadIdx.x] = c;
  __syncthreads();
  for (int half = kGlobalMomentThreads / 2; half > 0; half /= 2) {
    if (threadIdx.x < half) {
      sS[threadIdx.x] = __dadd_rn(sS[threadIdx.x], sS[threadIdx.x + half]);
      sSS[threadIdx.x] = __dadd_rn(sSS[threadIdx.x], sSS[threadIdx.x + half]);
      sC[threadIdx.x] += sC[threadIdx.x + half];
    }
    __syncthreads();
  }
  if (threadIdx.x == 0) {
    p.partialS[blockIdx.x] = sS[0];
    p.partialSS[blockIdx.x] = sSS[0];
    p.partialCount[blockIdx.x] = sC[0];
  }
}

}  // namespace

void launchGlobalMoments(const GlobalMomentsLaunch& p, cudaStream_t s) {
  globalMomentsKernel<<<kGlobalMomentBlocks, kGlobalMomentThreads, 0, s>>>(p);
  checkLaunch("globalMomentsKernel");
}

}  // namespace st::gpu

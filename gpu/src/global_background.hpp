#pragma once
// stats::globalBackground (the one-sided clip of every unmasked finite pixel of up to 50 evenly spaced
// frames) on a cube already on the device (issue 16: 0.5 s on the host for 1500 x 512^2, ~1 ms here).
#include <cuda_runtime.h>

#include <cstddef>
#include <cstdint>

namespace st::gpu {

inline constexpr int kGlobalMomentBlocks = 264;  // 2 per SM of an H100
inline constexpr int kGlobalMomentThreads = 256;

/// One pass of the clip's moments over the samples y <= hi of the frames listed (kernels in
/// global_background_kernels.cu). Device pointers; partials: [kGlobalMomentBlocks] each.
struct GlobalMomentsLaunch {
  const float* pix;
  const std::uint8_t* mask;  ///< or null
  const int* frames;
  int nFrames;
  std::size_t framePixels;
  double hi;
  double shift;
  double* partialS;
  double* partialSS;
  unsigned long long* partialCount;
};

void launchGlobalMoments(const GlobalMomentsLaunch& p, cudaStream_t s);

}  // namespace st::gpu

#pragma once
// Registration's sampled links on the device (issue 16; detect::RegistrationLinkBatch): the frames' star
// images as core/detect/registration_links.cpp makes them (the same floats), their cross-correlation through
// the shared-memory FFT of phase_fft_device.cuh (its floats differ from FFTW's r2c/c2r by rounding), the
// high-pass, and each pair's first largest value, parabolic vertex and significance.
#include <cuda_runtime.h>

#include <cstddef>
#include <cstdint>

#include "phase_correlation_kernels.hpp"

namespace st::gpu {

struct RegistrationLinkLaunch {
  // The star images.
  const float* frames = nullptr;        ///< the cube on the device (frame-major, width x height floats each)
  const std::uint8_t* masks = nullptr;  ///< slots x width x height: the slots' frames' masks, or null
  const int* slotFrame = nullptr;       ///< the cube frame of each slot
  int slots = 0;
  int width = 0, height = 0;  ///< the frames'
  int bin = 1;
  int bw = 0, bh = 0;             ///< the star images' (width / bin, height / bin)
  float* samples = nullptr;       ///< slots x sampleStride, work
  std::size_t sampleStride = 0;   ///< >= ceil(width x height / 7)
  float* median = nullptr;        ///< slots, work: each frame's sampled median
  float* sigma = nullptr;         ///< slots, work: and its sigma
  const float* taperX = nullptr;  ///< bw values
  const float* taperY = nullptr;  ///< bh values
  float* images = nullptr;        ///< slots x bw x bh, the star images
  // The correlations.
  PhaseFftAxis x, y;                ///< x.n == bw, y.n == bh
  float2* spectra = nullptr;        ///< slots x bh x bw, work
  const float* highPass = nullptr;  ///< bh x (bw / 2 + 1)
  const int* pairSlots = nullptr;   ///< pairs x 2: the later frame's slot, the earlier's
  int pairs = 0;
  float2* products = nullptr;  ///< pairs x bh x bw, work
  float* surface = nullptr;    ///< pairs x bh x bw, the correlation surfaces
  float* rowMax = nullptr;     ///< pairs x bh, work
  int* rowArg = nullptr;       ///< pairs x bh, work
  double* rowSum = nullptr;    ///< pairs x bh, work
  double* rowSum2 = nullptr;   ///< pairs x bh, work
  double* peaks = nullptr;     ///< pairs x 3 out: step x, step y (binned px), significance
};

/// Star images of every slot, each slot's row transforms, each pair's column transforms with A conj(B)
/// high-passed and transformed back, the row transforms back into the surfaces, and each pair's peak.
/// Throws st::GpuError on a failed launch.
void launchRegistrationLinks(const RegistrationLinkLaunch& p, cudaStream_t s);

}  // namespace st::gpu

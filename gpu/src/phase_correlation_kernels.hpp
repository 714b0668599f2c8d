#pragma once
// The sky rate's phase correlations on the device (issue 16): detect::detail::phaseShift for a batch of image
// pairs, with a mixed-radix (2, 3, 4, 5) complex FFT of our own in shared memory (cuFFT is not linked: its
// library is larger than a device run can carry). The transforms' floats differ from FFTW's by rounding;
// the cross-power normalisation, the peak's choice and its 5 x 5 centroid are the CPU's arithmetic.
#include <cuda_runtime.h>

#include <vector>

namespace st::gpu {

/// The largest transform length the kernels take (a column pass holds two columns of it in shared memory).
constexpr int kMaxPhaseFftSize = 8192;

/// The radices of n's stages, 4s first, then 2, 3 and 5; empty when n has another prime factor, is < 2 or
/// > kMaxPhaseFftSize.
std::vector<int> phaseFftRadices(int n);

/// exp(-2 pi i t / n) for t < n, computed in double and rounded to float.
std::vector<float2> phaseFftTwiddles(int n);

/// The radices of one axis as the kernels take them.
struct PhaseFftAxis {
  int n = 0;
  int stages = 0;
  int radix[16] = {};
  const float2* twiddle = nullptr;  ///< phaseFftTwiddles(n), on the device
};

struct PhaseCorrelationLaunch {
  const float* images = nullptr;  ///< pairs x 2 images (a, then b) of width x height floats, windowed
  int width = 0, height = 0;
  PhaseFftAxis x, y;  ///< transform sizes x.n >= width, y.n >= height (zero padding)
  int pairs = 0;
  float2* spectra = nullptr;  ///< pairs x 2 x x.n x y.n, work
  float* surface = nullptr;   ///< pairs x x.n x y.n, the correlation surfaces
  float* rowMax = nullptr;    ///< pairs x y.n, work
  int* rowArg = nullptr;      ///< pairs x y.n, work
  /// pairs x 4 out: the offset of b relative to a (x, y, px), the response, and 1 where the surface was
  /// finite (else 0: the pair is for the CPU).
  double* peaks = nullptr;
};

/// Row transforms of every image, the column transforms with the normalised cross-power spectrum and its
/// inverse column transform, the inverse row transforms into the surfaces with each row's peak, and each
/// pair's peak and centroid. Throws st::GpuError on a failed launch.
void launchPhaseCorrelation(const PhaseCorrelationLaunch& p, cudaStream_t s);

}  // namespace st::gpu

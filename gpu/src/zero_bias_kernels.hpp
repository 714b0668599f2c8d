#pragma once
// Kernels of the stages between the per-pixel background and the residual means on a cube kept on the
// device (issue 16; host side in zero_bias.cpp): detect::subtractStarTemplate (the per-block template sums,
// the subtraction with its per-position residual variance, the whitening) and the zeroing stages
// (calib::zeroPixels, detect::zeroMasked, detect::zeroUnmeasured, detect::zeroSingleFrameSources). Plain
// structs only (C++17, no core headers); pointers are device pointers, cubes frame-major.
#include <cuda_runtime.h>

#include <cstddef>
#include <cstdint>

namespace st::gpu {

/// Per-frame Lanczos-3 tables of the star template (detect::lanczos3Weights): the mask's integer shift,
/// the first tap's offset and the six normalised weights along x and y.
struct LanczosFrames {
  const int* sx;
  const int* sy;
  const int* ox;
  const int* oy;
  const double* wx;  ///< [nf][6]
  const double* wy;
};

/// The per-block sums and counts of the resampled frames at the grown region's canvas positions.
struct StarTemplateLaunch {
  const float* pix;
  const std::uint8_t* mask;  ///< or null
  int width, height;
  const int* positions;  ///< [np] canvas indices of the grown region
  int np;
  int cw, x0, y0;          ///< canvas width and origin
  const int* blockFrames;  ///< the frames of block b, ascending: blockFrames[blockStart[b], blockStart[b+1])
  const int* blockStart;   ///< [nb + 1]
  int nb;
  LanczosFrames lz;  ///< weights of +f
  float* sum;        ///< [nb][np]
  float* cnt;        ///< [nb][np]
};
void launchStarTemplateSums(const StarTemplateLaunch& p, cudaStream_t s);

/// Block b's template from the block sums of the blocks outside its window (excluded[b * nb + o] = 1 for
/// those inside), the CPU's double sums over o in order: tmpl[b][positions[k]] = float(s / c) and valid = 1
/// where c >= minFrames (tmpl and valid zeroed before); framesSum/framesN: totals of those c and positions.
void launchStarTemplateBuild(const float* sum, const float* cnt, int np, int nb, const std::uint8_t* excluded,
                             const int* positions, std::size_t canvasSize, double minFrames, float* tmpl,
                             std::uint8_t* valid, unsigned long long* framesSum, unsigned long long* framesN,
                             cudaStream_t s);

/// The subtraction of each frame's block template (weights of -f), one thread per target position over
/// the frames in order.
struct StarSubtractLaunch {
  float* pix;
  int width, height, nf;
  const int* targets;  ///< [nt] canvas indices of the region
  int nt;
  int cw, ch, x0, y0;
  const int* blockOf;  ///< [nf]
  LanczosFrames lz;
  const float* tmpl;          ///< [nb][cw * ch]
  const std::uint8_t* valid;  ///< [nb][cw * ch]
  const float* sigma;         ///< per-pixel background sigma (width x height), or null
  double* r2;                 ///< [nt] out (with sigma)
  double* s2;
  float* samples;
  unsigned long long* counts;  ///< [2] out: pixel-frames subtracted, zeroed (non-zero ones)
};
void launchStarSubtract(const StarSubtractLaunch& p, cudaStream_t s);

/// f[x0 + pos % cw + sx_n, y0 + pos / cw + sy_n] *= factor in every frame where it lies inside.
void launchWhiten(float* pix, int width, int height, int nf, const int* positions, const float* factors,
                  int count, int cw, int x0, int y0, const int* sx, const int* sy, cudaStream_t s);

/// pix[i] = 0 for every listed flat index i < total.
void launchZeroIndices(float* pix, std::size_t total, const std::uint64_t* idx, std::size_t count,
                       cudaStream_t s);

/// Zeroes the reference positions (xy pairs) moved by each frame's shift; counts the pixels inside.
void launchZeroMasked(float* pix, int width, int height, int nf, const int* xy, int count, const int* sx,
                      const int* sy, unsigned long long* zeroed, cudaStream_t s);

/// Zeroes the listed pixels in every frame; counts those not already 0 in every frame.
void launchZeroUnmeasured(float* pix, std::size_t framePixels, int nf, const int* pixels, int count,
                          unsigned long long* zeroed, cudaStream_t s);

/// detect::zeroSingleFrameSources: seeds (value >= snr x sigma, not covered by `keep`), then discs.
struct SingleFrameLaunch {
  float* pix;
  int width, height, nf;
  const float* sigma;  ///< per pixel, or null: sigmaN
  double sigmaN, snr;
  int radius;
  // keep: a moving mask (canvas cw x ch at x0, y0; per-frame shifts), or canvas null
  const std::uint8_t* keepCanvas;
  int keepCw, keepCh, keepX0, keepY0;
  const int* keepSx;
  const int* keepSy;
  std::uint64_t* seeds;  ///< capacity seedCap: flat cube indices
  unsigned long long seedCap;
  unsigned long long* seedCount;       ///< [1]
  unsigned long long* seedsPerFrame;   ///< [nf]
  unsigned long long* zeroedPerFrame;  ///< [nf]
};
void launchSingleFrameSeeds(const SingleFrameLaunch& p, cudaStream_t s);
void launchSingleFrameZero(const SingleFrameLaunch& p, unsigned long long seeds, cudaStream_t s);

/// stats::estimateNoiseModel's frame scales: for each frame n, the values f^2 / v (double) of the pixels
/// i = n % stride + k stride with f != 0 finite and v > 0, their count, and the element of rank count / 2
/// (std::nth_element's) by a radix select on the doubles' bits (non-negative: ordered as integers).
void launchFrameMedians(const float* pix, const float* variance, std::size_t framePixels, int nf, int stride,
                        double* median, unsigned* count, cudaStream_t s);

}  // namespace st::gpu

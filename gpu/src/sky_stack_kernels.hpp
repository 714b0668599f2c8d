#pragma once
// detect::stackAtSkyRate on a cube already on the device (issue 16: the stacks the static-source search and
// the PSF stage ask for, made from the prefetched calibrated cube).
#include <cuda_runtime.h>

#include <cstddef>
#include <cstdint>

namespace st::gpu {

struct SkyStackLaunch {
  const float* pix = nullptr;          ///< nf frames of width x height, frame-major
  const std::uint8_t* mask = nullptr;  ///< the cube's mask, or null
  int width = 0, height = 0;
  const int* shiftX = nullptr;  ///< MovingMask::shiftX(n), per frame of the cube
  const int* shiftY = nullptr;
  int first = 0, last = 0;  ///< frames [first, last)
  int x0 = 0, y0 = 0;       ///< the canvas origin (MovingMask::x0, y0)
  int cw = 0, ch = 0;       ///< the canvas
  double subtract = 0.0;
  float* mean = nullptr;  ///< cw x ch outputs (SkyStack::mean, count, max)
  float* count = nullptr;
  float* max = nullptr;
};

/// One thread per canvas pixel, its frames in order: the CPU's double sums in its order (no multiply, so
/// nothing to contract: equal stacks), count and maximum as std::max.
void launchSkyStack(const SkyStackLaunch& p, cudaStream_t s);

/// detect::shiftedSums of k blocks on a cube already on the device: one thread per (pixel, block), the
/// block's frames in order, the CPU's double arithmetic (equal sums).
struct ShiftedSumsLaunch {
  const float* pix = nullptr;
  const std::uint8_t* mask = nullptr;  ///< or null
  int width = 0, height = 0;
  int blocks = 0;
  const int* first = nullptr;  ///< per block: its first frame
  const int* start = nullptr;  ///< per block + 1: its first entry in sx/sy (the block's frames in order)
  const int* sx = nullptr;
  const int* sy = nullptr;
  double background = 0.0;
  double* sum = nullptr;  ///< blocks x width x height
  double* count = nullptr;
  /// Instead of sum and count when not null (detect::ShiftedSums::mean, frames): sum / count rounded to
  /// float (0 where count is 0), and count as a float.
  float* mean = nullptr;
  float* frames = nullptr;
  /// Instead of all the above when not null (detect::ShiftedSums::doubleMean): sum / count, 0 where count
  /// is 0.
  double* doubleMean = nullptr;
};
void launchShiftedSums(const ShiftedSumsLaunch& p, cudaStream_t s);

/// detect::FilteredSnrInputs's SNR map (width x height) into `out`, the CPU's values bit for bit.
void launchFilteredSnr(const float* rc, const float* count, const double* k, int width, int height, int r,
                       double sigma, float* out, cudaStream_t s);

/// calib::cosmicRayPreTestWords of nf >= 3 frames of np pixels (nf * np < 2^37): one thread a pixel, a
/// warp's 32 verdicts one word (__ballot_sync), the CPU's float subtraction and std::max. Each non-zero word
/// w goes to out[slot] = w << 32 | word for a slot taken from *count (in no particular order; written only
/// while slot < capacity, *count still counts them all). *count must be 0 on entry.
void launchCosmicRayPreTest(const float* pix, std::size_t nf, std::size_t np, float thr,
                            unsigned long long* out, unsigned long long capacity, unsigned long long* count,
                            cudaStream_t s);

/// pix[index[k]] = value[k] for k < n (the cosmic-ray fills patched into a prefetched cube).
void launchScatter(float* pix, const std::uint64_t* index, const float* value, std::size_t n, cudaStream_t s);
/// mask[index[k]] = value[k] for k < n (a sparse mask uploaded: its non-zero bytes into a zeroed buffer).
/// mask[n * np + pixels[j]] = 1 for every frame n < nf and j < count (detect::maskPixelsInAllFrames).
void launchMaskInAllFrames(std::uint8_t* mask, const std::uint64_t* pixels, std::size_t count, std::size_t nf,
                           std::size_t np, cudaStream_t s);
void launchScatter(std::uint8_t* mask, const std::uint64_t* index, const std::uint8_t* value, std::size_t n,
                   cudaStream_t s);

}  // namespace st::gpu

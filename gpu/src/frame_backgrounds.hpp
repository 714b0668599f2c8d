#pragma once
// stats::removeFrameBackgrounds (core/stats/noise_model.cpp: SEP's sep_background per frame, its spline
// subtracted, the median level restored) on the device (issue 16). The work is split as SEP splits it:
//   - per mesh (one block per frame and mesh): backstat (the clipped mean and sigma, double sums reduced in
//     a fixed order: they differ from SEP's sequential sums by their rounding only), the histogram (SEP's
//     float bin arithmetic, no fused multiply-adds) and backguess (the clipped-histogram mode; its sums are
//     integers, exact in any order, and its two-sided median walk is found from the histogram's prefix sums:
//     the walk advances the low side past bin i exactly when P_i + P_{i+1} < T, P the prefix counts of the
//     range and T its total, so the same bins as SEP's serial walk);
//   - per frame on the host (64 meshes a frame): filterback (the bad meshes' nearest-neighbour fill, the
//     median filter, the global level and rms) and makebackspline (the y second derivatives), SEP's float and
//     double steps as SEP writes them;
//   - per row and pixel (one block per frame and row): the node values along y, the x second derivatives
//     and the bicubic spline along x (SEP's float arithmetic, its column steps from a host table), the
//     background subtracted and the restored level added back, as the CPU does.
// The hot pixels' per-pixel excess is made from the same kept frames. Plain structs only (C++17).
#include <cuda_runtime.h>

#include <functional>

#include <cstddef>
#include <cstdint>

#include "st/stats/sep_background.hpp"

namespace st::gpu {

/// SEP's constants (sepcore.h, background.c).
inline constexpr double kSepBig = stats::sep::kBig;
inline constexpr int kSepMaxLevels = stats::sep::kMaxLevels;

struct SepMeshLaunch {
  const float* pix;          ///< nf frames of width x height
  const std::uint8_t* mask;  ///< same layout (masked when non-zero), or null
  int width, height, nf;
  int bw, bh;    ///< mesh size (SEP's bw, bh)
  int nx, ny;    ///< meshes per row / column
  double step;   ///< sqrt(2 / PI) * QUANTIF_NSIGMA / QUANTIF_AMIN with SEP's PI
  float* back;   ///< out: [nf][ny][nx] backguess mode (-BIG for a bad mesh)
  float* sigma;  ///< out: [nf][ny][nx] backguess sigma (-BIG for a bad mesh)
};

/// SEP's backstat + backhisto + backguess for every (frame, mesh).
void launchSepMeshes(const SepMeshLaunch& p, cudaStream_t s);

/// calib::applyPixelCalibration in place on nf frames of np pixels: v = f - overscan[n], then - bias[i],
/// - darkPerS[i] * darkSeconds[n], / flat[i] where given (not null), each step rounded to float as on the
/// CPU (no fused multiply-add).
struct PixelCalibrationLaunch {
  float* pix;
  std::size_t nf, np;
  const float* overscan;     ///< per frame
  const float* darkSeconds;  ///< per frame
  const float* bias;         ///< np, or null
  const float* darkPerS;     ///< np, or null
  const float* flat;         ///< np, or null
};
void launchPixelCalibration(const PixelCalibrationLaunch& p, cudaStream_t s);

/// The per-row and per-column constants of SEP's spline evaluation, made on the host (core's tables).
using SepRow = stats::sep::SplineRow;
using SepColumn = stats::sep::SplineColumn;

struct SepSubtractLaunch {
  float* pix;  ///< nf frames of width x height, written in place
  int width, height, nf;
  int nx, ny;
  const float* back;      ///< [nf][ny][nx] filtered mesh values
  const float* dback;     ///< [nf][ny][nx] their y second derivatives
  const SepRow* rows;     ///< [height] (unused when ny == 1)
  const SepColumn* cols;  ///< [width] (unused when nx == 1)
  float restored;         ///< added back after the subtraction
};

/// pix -= SEP's background spline, then pix += restored (float, as the CPU).
void launchSepSubtract(const SepSubtractLaunch& p, cudaStream_t s);

}  // namespace st::gpu

#include <vector>

namespace st::gpu {

/// What the host side of removeFrameBackgroundsOnDevice reports.
struct SepFrameBackgrounds {
  std::vector<double> level, rms;  ///< SEP's global level and rms per frame
  double restored = 0.0;           ///< the median of the finite levels, added back
  double meshSeconds = 0.0, hostSeconds = 0.0, subtractSeconds = 0.0;
};

/// stats::removeFrameBackgrounds(cube, {meshPx, filterCells}) on `pix` (nf frames of width x height on the
/// current device, written in place; `mask` the cube's mask there, or null): SEP with bw = min(max(8,
/// meshPx), width), bh = min(max(8, meshPx), height), fw = fh = max(1, filterCells), fthresh 0. Throws
/// st::GpuError on a CUDA failure. With `framesPerChunk` > 0 and `chunkReady`, the meshes are measured chunk
/// by chunk of frames, chunkReady(f0, f1) called first for each (it queues on `stream` what frames [f0, f1)
/// need first: their upload, their calibration), so that the upload of the next chunks runs beside them.
SepFrameBackgrounds removeFrameBackgroundsOnDevice(float* pix, const std::uint8_t* mask, int width,
                                                   int height, int nf, int meshPx, int filterCells,
                                                   cudaStream_t stream, int framesPerChunk = 0,
                                                   const std::function<void(int, int)>& chunkReady = {});

/// detect::findHotPixels's per-pixel excess from frames on the device (the frames the frame backgrounds
/// keep): for each pixel, the smallest over `blocks` blocks of float(sum / count - background), the sum of
/// its unmasked samples in frame order in double (the CPU's order and arithmetic), 0 without samples.
void launchHotPixelExcess(const float* pix, const std::uint8_t* mask, std::size_t framePixels, int nf,
                          int blocks, double background, float* minExcess, cudaStream_t s);

}  // namespace st::gpu

#pragma once
// The noise model for real frames (ARCHITECTURE.md, "SNR of the search statistic"). Real frames differ in sky
// level, gradient and noise from one exposure to the next, and the flat-fielded noise varies over the frame
// (vignetting); one pooled sigma is wrong for all of them. Three steps, in the pre-processing order:
//
//  1. removeFrameBackgrounds: each frame's own smooth background (SEP, the SExtractor library: a mesh of
//     clipped modes, median-filtered, spline-interpolated) is subtracted and the cube's median sky level
//     added back, before the per-pixel background, so that frame-to-frame sky offsets and gradients do not
//     inflate the per-pixel scatter (on Lowell 42-inch frames they did 4-7x).
//  2. removeResidualMeans: after the per-pixel background and the masking, each zero-biased frame's residual
//     local *mean* (a mesh of clipped means) is removed. The matched filter amplifies a mean sum(K)/sqrt(sum
//     K^2) ~ 6x more than noise; a one-sided clip on skewed EMCCD noise leaves +0.012 sigma, i.e. +0.073
//     sqrt(N) of SNR on every track.
//  3. estimateNoiseModel: the variance of frame n at pixel q is modelled as s_n^2 v(q): v from the per-pixel
//     frame-to-frame scatter (smoothed robustly), s_n^2 each frame's robust variance relative to v.
//     stack::filterCube then forms the inverse-variance-weighted matched filter from it.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "st/common/frame_cube.hpp"
#include "st/common/image.hpp"
#include "st/common/progress.hpp"

namespace st::stats {

struct FrameBackgroundParams {
  bool enabled = true;
  int meshPx = 64;      ///< SEP tile (SExtractor's default 64)
  int filterCells = 3;  ///< median filter of the mesh, in tiles (SExtractor's default 3)
};

struct FrameBackgrounds {
  std::vector<double> level;      ///< each frame's global background (SEP's global mean), counts
  std::vector<double> rms;        ///< each frame's global background rms (SEP), counts
  double restoredLevel = 0.0;     ///< the median of `level`, added back to every frame
  std::size_t framesSkipped = 0;  ///< frames SEP could not model (left as they were)
};

/// Subtracts from every frame its smooth background minus the cube's median level (so the frames keep a
/// typical sky level: saturation levels and the scalar background stay meaningful). Masked and non-finite
/// pixels are ignored by SEP and left as they are. Parallel over frames. Throws st::Cancelled.
FrameBackgrounds removeFrameBackgrounds(FrameCube& cube, const FrameBackgroundParams& params,
                                        ProgressSink& progress, CancelToken& cancel);

/// In zero-biased frames (0 = masked or zeroed): the mean of each meshPx x meshPx cell over non-zero
/// pixels, clipped at +-clipSigma (iterated), bilinearly interpolated between cell centres, subtracted from
/// the non-zero pixels (zeros stay 0). Returns the rms over frames and cells of the means removed, counts.
double removeResidualMeans(FrameCube& cube, int meshPx, double clipSigma, ProgressSink& progress,
                           CancelToken& cancel);

/// Variance of frame n at pixel q: frameScale[n]^2 * variance(q).
struct NoiseModel {
  Image variance;                  ///< v(q), counts^2; 0 where unknown (weight 0)
  std::vector<double> frameScale;  ///< s_n, ~1 (median 1)
  double sigmaRef = 0.0;           ///< sqrt(median v) * median s: the uniform-noise equivalent, counts
  /// The number of frames whose own pixel grid covers each pixel (frames moved by whole pixels onto frame
  /// 0's grid: detect::alignedCoverage); empty: every frame covers every pixel. The weighted matched filter
  /// averages each pixel's weight over these frames only (stack/matched_filter.hpp).
  std::vector<std::uint32_t> framesCovering;
  [[nodiscard]] bool empty() const noexcept { return variance.empty(); }
  /// A uniform model: variance sigma^2 everywhere, every s_n = 1 (the paper's statistic).
  static NoiseModel uniform(int width, int height, std::size_t frames, double sigma);
};

struct NoiseModelParams {
  int smoothBoxPx = 15;  ///< box of the smoothing of the per-pixel variance
  /// > 0: a pixel whose own variance exceeds this x the smooth one keeps its own. Off: a mover's or a star
  /// residual's signal inflates the frame-to-frame scatter of the pixels it crosses, and weighting those down
  /// cost a bright slow mover 70% of its SNR (tests/core/test_pipeline_movers.cpp); noisy pixels are masked
  /// by the hot-pixel and calibration stages instead.
  double noisyPixelRatio = 0.0;
  int sampleStride = 3;  ///< every n-th pixel enters s_n
};

/// The model from zero-biased frames and the per-pixel frame-to-frame sigma of the background stage
/// (`pixelSigma`; pixels flagged in `unmeasured` take no part in the smoothing). s_n^2 is the median over
/// non-zero pixels of F_n^2 / v divided by the median of chi^2_1 (0.4549), normalised to median 1 over the
/// frames. Throws st::InputError when the sizes differ or no pixel has a variance.
NoiseModel estimateNoiseModel(const FrameCube& zeroBiased, const Image& pixelSigma,
                              const std::vector<std::uint8_t>& unmeasured, const NoiseModelParams& params,
                              CancelToken& cancel);

}  // namespace st::stats

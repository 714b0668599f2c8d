#pragma once
// Static stars removed from a drifting field by subtracting a sky-registered template (issue 14): where the
// star field drifts across the detector, masking each star down to one *stack* sigma zeroes wide discs
// that follow the stars, and an object moving slowly relative to the stars (the paper's NEO moves 0.7 px/s
// against 16.4 px/s of drift) spends much of the span under them. Instead, each frame is resampled onto the
// sky (Lanczos-3 at its fractional offset), the template of frame n is the mean of the resampled frames
// outside +-window of t_n (so a mover, which has left its place by then, does not subtract itself), and the
// template, resampled back to frame n's offset, is subtracted there. Only the stars' cores, where single
// frames see them, are masked afterwards.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <utility>
#include <vector>

#include "st/common/frame_cube.hpp"
#include "st/common/image.hpp"
#include "st/common/progress.hpp"
#include "st/detect/moving_mask.hpp"

namespace st::detect {

struct StarSubtractionParams {
  /// Frames within +- windowFraction * span of a frame are left out of its template (as for the per-pixel
  /// background: an object moving >= one FWHM relative to the sky in that time keeps its flux).
  double windowFraction = 0.25;
  int blocks = 16;  ///< frames are grouped in this many blocks of consecutive times, one template per block
  /// Sky positions whose residuals, over the frames, vary more than the background there: the ratio R =
  /// sum r^2 / sum sigma^2 over >= minExcessSamples frames, significant at excessSignificance times its
  /// scatter sqrt(2 / S) about 1 for S samples. The excess is the star's photon noise (an EMCCD's star at 2
  /// single-frame sigma doubles the variance), seeing changes and the interpolation's error, which the
  /// detector-fixed noise model cannot carry along with the sky. Up to maxVarianceRatio the residuals there
  /// are whitened (divided by sqrt(R), so their variance is the background's, as the noise model and the
  /// search's false-alarm probability assume): a mover crossing a faint star keeps its signal at the weight
  /// the star's noise leaves it. Above, the position is masked (bright stars' structure). Masking everything
  /// above 1.3x zeroed 31% of the PSF^2-weighted track of paper-neo seed 24's asteroid, which crossed a
  /// V = 22.5 star (search SNR -38% of the expected).
  double maxVarianceRatio = 4.0;
  double excessSignificance = 3.0;
  double minExcessSamples = 20.0;
  /// A template pixel needs this many frames (its noise adds 1/minTemplateFrames of the variance).
  double minTemplateFrames = 10.0;
};

struct StarSubtraction {
  bool applied = false;
  std::size_t pixelsSubtracted = 0;   ///< pixel-frames from which a template value was subtracted
  std::size_t pixelsZeroed = 0;       ///< pixel-frames of the region without a template there: zeroed
  std::size_t whitenedPositions = 0;  ///< sky positions whose residuals were divided by sqrt(R) <= 2
  std::size_t excessPositions = 0;    ///< sky positions with R > maxVarianceRatio (before dilation)
  /// Those positions, dilated by 1 px, following the sky (same geometry as the region): to be zeroed.
  MovingMask excess;
  double meanTemplateFrames = 0.0;  ///< frames averaged per template pixel, mean over the region
};

/// Subtracts, in every frame of the zero-biased `cube`, the sky-registered template of the stars at the
/// positions that `region` (a MovingMask at `region.rate()`, e.g. the stars' wide footprints) covers in
/// that frame. Pixels whose template lacks samples (a star seen only within one window, canvas edges) are
/// zeroed. With `sigma` (the per-pixel frame-to-frame sigma of the background, detector pixels), the
/// residuals at sky positions with a moderate excess of variance are whitened, and those with a large one
/// returned in `excess`. Not applied (cube untouched,
/// `applied` false) when no block lies outside another's window. Throws st::Cancelled.
StarSubtraction subtractStarTemplate(FrameCube& cube, const MovingMask& region, const Image* sigma,
                                     const StarSubtractionParams& params, ProgressSink& progress,
                                     CancelToken& cancel);

/// Lanczos-3 weights for sampling at position f relative to an integer pixel: six taps starting at the
/// returned offset (floor(f) - 2), normalised to 1.
int lanczos3Weights(double f, double w[6]);

/// What subtractStarTemplate prepares before it reads a pixel (shared with the GPU path, issue 16).
struct StarTemplatePlan {
  std::vector<int> targets;    ///< canvas positions (indices into region's canvas) the region sets
  std::vector<int> positions;  ///< the template's positions: the region grown by 5 px (the taps' reach)
  int blocks = 0;              ///< blocks of consecutive times, equal counts
  std::vector<int> blockOf;    ///< frame -> its block
  /// blocks x blocks, [b * blocks + c]: block c's time range comes within the window of block b's (left out
  /// of b's template).
  std::vector<std::uint8_t> excluded;
};

/// subtractStarTemplate's plan; none when it does not apply (region empty or of another frame count, fewer
/// than 4 frames, no block outside another's window).
std::optional<StarTemplatePlan> planStarTemplate(const FrameCube& cube, const MovingMask& region,
                                                 const StarSubtractionParams& params);

/// Frame n's sub-pixel offset beyond region's integer shift (dt: its time offset, s): the true sky motion
/// (registration offset plus the linear motion) is shift + this.
std::pair<double, double> starTemplateFractionalOffset(const MovingMask& region, const FrameCube& cube,
                                                       std::size_t n, double dt);

/// The verdict on one sky position's residuals: r2 = sum of squared residuals, s2 = sum of the background
/// variances, over `samples` frames. 0: left as it is; else the factor (1 / sqrt(R)) its residuals are
/// multiplied by, or -1: R > maxVarianceRatio, masked (StarSubtraction::excess).
double starResidualVerdict(double r2, double s2, double samples, const StarSubtractionParams& params);

}  // namespace st::detect

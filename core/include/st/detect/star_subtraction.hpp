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

#include "st/common/frame_cube.hpp"
#include "st/common/progress.hpp"
#include "st/detect/moving_mask.hpp"

namespace st::detect {

struct StarSubtractionParams {
  /// Frames within +- windowFraction * span of a frame are left out of its template (as for the per-pixel
  /// background: an object moving >= one FWHM relative to the sky in that time keeps its flux).
  double windowFraction = 0.25;
  int blocks = 16;  ///< frames are grouped in this many blocks of consecutive times, one template per block
};

struct StarSubtraction {
  bool applied = false;
  std::size_t pixelsSubtracted = 0;  ///< pixel-frames from which a template value was subtracted
  double meanTemplateFrames = 0.0;   ///< frames averaged per template pixel, mean over the region
};

/// Subtracts, in every frame of the zero-biased `cube`, the sky-registered template of the stars at the
/// positions that `region` (a MovingMask at `region.rate()`, e.g. the stars' wide footprints) covers in
/// that frame. Pixels whose template lacks samples (canvas edges) are left as they are. Not applied (and
/// `applied` false) when no block lies outside another's window. Throws st::Cancelled.
StarSubtraction subtractStarTemplate(FrameCube& cube, const MovingMask& region, const StarSubtractionParams& params,
                                     ProgressSink& progress, CancelToken& cancel);

/// Lanczos-3 weights for sampling at position f relative to an integer pixel: six taps starting at the
/// returned offset (floor(f) - 2), normalised to 1.
int lanczos3Weights(double f, double w[6]);

}  // namespace st::detect

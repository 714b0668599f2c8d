#pragma once
// The residual image of a co-moving fit at any parameters, for the live plot while the fit converges:
// data - model summed along the track. Matches fit::FitResult::residualStack at the final parameters (the
// same stamp grid and rounding), tested against it.
#include "st/common/frame_cube.hpp"
#include "st/common/image.hpp"
#include "st/fit/comoving_fit.hpp"

namespace st::ui {

/// Data - model of the co-moving model `p` (pixel-integrated Moffat `psf`, fit::PixelPsfTable), summed
/// over every frame of `frames` on a (2 half + 1)^2 grid centred on the rounded track of each frame,
/// positions at the cube's t_ref (the whole-cube fit's reference time). Out-of-frame, masked and non-finite
/// samples are skipped. Cost: one pass over (2 half + 1)^2 pixels of every frame.
[[nodiscard]] Image residualAlongTrack(const FrameCube& frames, const fit::FitParams& p,
                                       const psf::Moffat& psf, int half);

}  // namespace st::ui

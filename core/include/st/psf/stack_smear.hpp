#pragma once
// The extra blur of a star in a stack built with integer shifts (the sky-rate stack of the pre-processing,
// IPSA convention of ARCHITECTURE.md: frame n is shifted by round(v (t_n - t_ref))). Two things widen the
// star there beyond the Moffat PSF of the paper (\label{MoffatPsf}):
//   - the trail of each exposure: the star moves by v * exposure during a frame (0.98 px on paper-neo, whose
//     sky drifts 16.4 px/s in 1/16.7 s frames);
//   - the rounding of the shifts: frame n lands v (t_n - t_ref) - round(v (t_n - t_ref)) px (|.| <= 0.5) away
//     from the others.
// A Moffat fitted with no allowance for these is 2% too wide on paper-neo. SmearKernel lists the offsets
// with their weights so that the fit (st/psf/moffat_fit.hpp) can model the stack's PSF as the Moffat
// averaged over them and return the Moffat itself.
#include <vector>

#include "st/common/frame_cube.hpp"
#include "st/common/units.hpp"

namespace st::psf {

/// Offsets (px, along x and y) where copies of the PSF are summed, with weights summing to 1. Empty = none.
struct SmearKernel {
  std::vector<double> dx, dy, weight;
  [[nodiscard]] bool empty() const noexcept { return weight.empty(); }
};

/// The smear of a stack of the frames of `cube` at `rate` (px/s) with integer shifts: for every frame its
/// rounding residual plus points spread uniformly along its trail of rate * exposureS (FrameInfo), binned to
/// `binPx`. Binning adds about binPx^2 / 12 to the smear's variance (Sheppard's correction; 0.005 px^2 at
/// the default 1/4 px), which moves a fitted FWHM by < 0.1% at 3.5 px and < 0.4% at 2 px. An empty kernel
/// when the cube has no frames or no offset reaches binPx / 2 (a tracked, untrailed stack).
SmearKernel stackSmear(const FrameCube& cube, Velocity rate, double binPx = 0.25);

}  // namespace st::psf

#pragma once
// The image of a synthetic mover in one exposure and the matched-filter SNR of its whole track: the pure
// arithmetic of injection-recovery (ARCHITECTURE.md, "Validation beyond the simulator").
//
// A mover is a point source whose position is linear in time, x(t) = x0 + vx (t - t_ref) (ARCHITECTURE.md
// conventions: 0-based pixels, centres at integers, t_ref the mean mid-time). During an exposure it trails
// from x(t_mid - E/2) to x(t_mid + E/2); its image is the Moffat PSF (\label{MoffatPsf}) integrated over each
// pixel (Moffat::pixelMean) and averaged over equal-time sub-steps of the trail.
#include <vector>

#include "st/psf/moffat.hpp"

namespace st::inject {

/// A small image of weights at (x0, y0) of a frame (0-based; may stick out of the frame), row-major.
struct Stamp {
  int x0 = 0;
  int y0 = 0;
  int width = 0;
  int height = 0;
  std::vector<double> values;
  [[nodiscard]] double at(int x, int y) const { return values[static_cast<std::size_t>(y) * width + x]; }
  [[nodiscard]] double sum() const;
};

/// Radius (px) outside which a Moffat holds `lostFraction` of its flux, (1 + r^2/R^2)^(1 - beta) =
/// lostFraction, capped at maxFwhm x FWHM (heavy wings, beta near 1, would need huge stamps).
/// Defaults: 1e-3 of the flux, at most 5 FWHM. For the paper's R = 3.3, beta = 4 this is 9.9 px.
double stampRadiusPx(const psf::Moffat& psf, double lostFraction = 1e-3, double maxFwhm = 5.0);

/// The unit-flux image of a source moving at constant speed from (xa, ya) to (xb, yb) during one exposure
/// (pass the same point twice for no motion): the PSF's pixel means (4 x 4 Gauss-Legendre per pixel) at
/// ceil(length / maxStepPx) equal-time sub-steps (midpoints), each truncated at `radiusPx` from its centre,
/// averaged, then scaled to sum exactly 1 (the flux the truncation drops, <= lostFraction of stampRadiusPx,
/// is given back in proportion, so the flux put in is the flux asked for).
Stamp trailedStamp(const psf::Moffat& psf, double xa, double ya, double xb, double yb, double radiusPx,
                   double maxStepPx = 0.1);

/// The matched-filter information of a track: sum over frames n and pixels q of P_n(q)^2 / sigma_n^2, with
/// P_n the unit-flux stamp of frame n and sigma_n the noise of frame n there (counts). The optimal SNR of
/// a track of flux F (counts per frame) is F sqrt(this) (ARCHITECTURE.md, "SNR of the search statistic":
/// sum_n psi_n / sqrt(sum_n phi_n) at the true track, expectation F sqrt(sum_n phi_n)). Throws
/// st::InputError when the sizes differ or a sigma is not > 0.
double trackInformation(const std::vector<Stamp>& stamps, const std::vector<double>& sigma);

/// The flux (counts per frame) that gives a track of this information the SNR `snr`: snr / sqrt(info).
double fluxForSnr(double snr, double information);

}  // namespace st::inject

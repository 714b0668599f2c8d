#pragma once
// The Moffat PSF of the paper (\label{MoffatPsf}): P(x, y) = (1 + (x^2 + y^2) / R^2)^(-beta), peak 1 at the
// centre. FWHM W = 2 R sqrt(2^(1/beta) - 1).
#include <cmath>

namespace st::psf {

struct Moffat {
  double radius = 3.3;  ///< R, pixels (paper §3.3: R ~ 3.3)
  double beta = 4.0;    ///< beta (paper §3.3: beta ~ 4)

  /// P at offset (dx, dy) pixels from the centre; 1 at the centre.
  [[nodiscard]] double operator()(double dx, double dy) const noexcept {
    return std::pow(1.0 + (dx * dx + dy * dy) / (radius * radius), -beta);
  }
  /// Full width at half maximum, pixels.
  [[nodiscard]] double fwhm() const noexcept { return 2.0 * radius * std::sqrt(std::pow(2.0, 1.0 / beta) - 1.0); }
  /// Integral of P over the plane: pi R^2 / (beta - 1) (finite for beta > 1).
  [[nodiscard]] double integral() const noexcept { return M_PI * radius * radius / (beta - 1.0); }
  /// Integral of P^2 over the plane: pi R^2 / (2 beta - 1). sqrt of it enters the paper's detection_snr.
  [[nodiscard]] double integralOfSquare() const noexcept { return M_PI * radius * radius / (2.0 * beta - 1.0); }
  /// R for a given FWHM and beta (inverse of fwhm()).
  [[nodiscard]] static double radiusForFwhm(double fwhm, double beta) noexcept {
    return fwhm / (2.0 * std::sqrt(std::pow(2.0, 1.0 / beta) - 1.0));
  }
};

}  // namespace st::psf

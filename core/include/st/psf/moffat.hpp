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
  [[nodiscard]] double fwhm() const noexcept {
    return 2.0 * radius * std::sqrt(std::pow(2.0, 1.0 / beta) - 1.0);
  }
  /// Integral of P over the plane: pi R^2 / (beta - 1) (finite for beta > 1).
  [[nodiscard]] double integral() const noexcept { return M_PI * radius * radius / (beta - 1.0); }
  /// Integral of P^2 over the plane: pi R^2 / (2 beta - 1). sqrt of it enters the paper's detection_snr.
  [[nodiscard]] double integralOfSquare() const noexcept {
    return M_PI * radius * radius / (2.0 * beta - 1.0);
  }
  /// R for a given FWHM and beta (inverse of fwhm()).
  [[nodiscard]] static double radiusForFwhm(double fwhm, double beta) noexcept {
    return fwhm / (2.0 * std::sqrt(std::pow(2.0, 1.0 / beta) - 1.0));
  }
  /// The Moffat with this FWHM (pixels) and beta: the fallback when no star is usable for a fit. The default
  /// beta = 4 is the paper's value (§3.3, fitted on a 16th-magnitude star).
  [[nodiscard]] static Moffat fromFwhm(double fwhm, double beta = 4.0) noexcept {
    return Moffat{radiusForFwhm(fwhm, beta), beta};
  }
  /// Radius (pixels) beyond which P < fraction of its peak: R sqrt(fraction^(-1/beta) - 1). For R = 3.3,
  /// beta = 4 and fraction = 1e-3 this is 7.1 px.
  [[nodiscard]] double radiusAtFraction(double fraction) const noexcept {
    return radius * std::sqrt(std::pow(fraction, -1.0 / beta) - 1.0);
  }
  /// Mean of P over the unit pixel centred at offset (dx, dy), by an n x n Gauss-Legendre rule (n in 1..5,
  /// clamped; default 4: error < 3e-5 of the peak for FWHM >= 1.5 px, 2e-4 at 1 px, checked against a 400^2
  /// midpoint rule). This is what a detector records for a
  /// PSF of peak 1 centred at offset 0; n = 1 is point sampling.
  [[nodiscard]] double pixelMean(double dx, double dy, int n = 4) const noexcept {
    const GaussRule g = gaussRule(n);
    double sum = 0.0;
    for (int j = 0; j < g.n; ++j)
      for (int i = 0; i < g.n; ++i)
        sum += g.w[i] * g.w[j] * (*this)(dx + g.x[i], dy + g.x[j]);
    return sum;
  }

  /// Gauss-Legendre nodes and weights on [-0.5, 0.5] (weights sum to 1), n in 1..5 (clamped).
  struct GaussRule {
    int n;
    double x[5];
    double w[5];
  };
  [[nodiscard]] static GaussRule gaussRule(int n) noexcept {
    switch (n <= 1 ? 1 : n >= 5 ? 5 : n) {
      case 1:
        return {1, {0.0}, {1.0}};
      case 2:
        return {2, {-0.28867513459481287, 0.28867513459481287}, {0.5, 0.5}};
      case 3:
        return {3,
                {-0.3872983346207417, 0.0, 0.3872983346207417},
                {0.2777777777777778, 0.4444444444444444, 0.2777777777777778}};
      case 4:
        return {4,
                {-0.4305681557970263, -0.16999052179242816, 0.16999052179242816, 0.4305681557970263},
                {0.17392742256872692, 0.32607257743127305, 0.32607257743127305, 0.17392742256872692}};
      default:
        return {5,
                {-0.453089922969332, -0.26923465505284155, 0.0, 0.26923465505284155, 0.453089922969332},
                {0.11846344252809454, 0.23931433524968324, 0.28444444444444444, 0.23931433524968324,
                 0.11846344252809454}};
    }
  }
};

}  // namespace st::psf

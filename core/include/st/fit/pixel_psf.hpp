#pragma once
// The Moffat PSF (st/psf/moffat.hpp, paper \label{MoffatPsf}) integrated over a pixel, as the co-moving fit
// uses it. The pixel average is evaluated on a 3x3 grid of sub-pixel centres (offsets -1/3, 0, +1/3 px,
// equal weights 1/9): the midpoint rule over nine 1/3-px sub-pixels. The simulator renders by integrating
// over pixels with sub-sampling too, so data and model agree to the accuracy of the sub-sampling: for
// R = 3.3, beta = 4 (W ~ 2.9 px) the 3x3 rule is within 0.7% of the exact pixel integral at the peak and
// the total over pixels is exact to 1e-4.
#include <vector>

#include "st/psf/moffat.hpp"

namespace st::fit {

/// Value and gradient of the pixel-integrated PSF.
struct PsfSample {
  double value =
      0.0;          ///< mean of P over the pixel (peak ~1 for a centred source; sum over pixels = integral)
  double du = 0.0;  ///< d value / d u, u = pixel x - source x (pixels^-1)
  double dv = 0.0;  ///< d value / d v, v = pixel y - source y
};

/// Pixel-integrated Moffat at offset (u, v) = (pixel centre - source centre), pixels. With gradient.
[[nodiscard]] PsfSample pixelPsf(const psf::Moffat& psf, double u, double v) noexcept;

/// Pixel-integrated Moffat value only (no gradient).
[[nodiscard]] double pixelPsfValue(const psf::Moffat& psf, double u, double v) noexcept;

/// A fast evaluator of pixelPsf for the fit's inner loop. The Moffat is radial, P = g(s) with
/// s = r^2 / R^2 and g(s) = (1 + s)^(-beta), and g'(s) = -beta g / (1 + s); g is tabulated on a uniform grid
/// in s (2^17 points up to the s of `maxRadiusPx`) and interpolated linearly: the error is below 3e-6 of the
/// peak for maxRadiusPx <= 30 and R >= 3 (tested against pixelPsf). Offsets beyond the table use the exact
/// formula. Immutable after construction, so it may be shared between threads.
class PixelPsfTable {
 public:
  PixelPsfTable(const psf::Moffat& psf, double maxRadiusPx);
  [[nodiscard]] PsfSample sample(double u, double v) const noexcept;
  [[nodiscard]] double value(double u, double v) const noexcept;

 private:
  [[nodiscard]] double g(double s) const noexcept;
  psf::Moffat m_psf;
  double m_invR2 = 0.0;
  double m_sMax = 0.0;
  double m_scale = 0.0;  // table index per unit s
  std::vector<double> m_g;
};

/// Sum over pixels of the squared pixel-integrated PSF centred on a pixel centre, the sqrt of which enters
/// the paper's detection_snr. Summed over a square of half-size ceil(8 W) + 4 px (the Moffat tail beyond
/// holds < 1e-6 of the sum for beta >= 2). Slightly below Moffat::integralOfSquare() because of the pixel
/// integration.
[[nodiscard]] double pixelPsfSumOfSquares(const psf::Moffat& psf);

}  // namespace st::fit

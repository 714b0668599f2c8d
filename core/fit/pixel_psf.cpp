#include "st/fit/pixel_psf.hpp"

#include <cmath>

namespace st::fit {
namespace {

constexpr double kSub[3] = {-1.0 / 3.0, 0.0, 1.0 / 3.0};
constexpr double kWeight = 1.0 / 9.0;

}  // namespace

PsfSample pixelPsf(const psf::Moffat& psf, double u, double v) noexcept {
  const double invR2 = 1.0 / (psf.radius * psf.radius);
  const double beta = psf.beta;
  PsfSample s;
  for (double sy : kSub) {
    const double yy = v + sy;
    for (double sx : kSub) {
      const double xx = u + sx;
      const double q = 1.0 + (xx * xx + yy * yy) * invR2;
      const double f = std::exp(-beta * std::log(q));
      // dP/dxx = -beta q^(-beta-1) 2 xx / R^2
      const double g = -2.0 * beta * invR2 * f / q;
      s.value += f;
      s.du += g * xx;
      s.dv += g * yy;
    }
  }
  s.value *= kWeight;
  s.du *= kWeight;
  s.dv *= kWeight;
  return s;
}

double pixelPsfValue(const psf::Moffat& psf, double u, double v) noexcept {
  const double invR2 = 1.0 / (psf.radius * psf.radius);
  double sum = 0.0;
  for (double sy : kSub) {
    for (double sx : kSub) {
      const double xx = u + sx;
      const double yy = v + sy;
      sum += std::exp(-psf.beta * std::log1p((xx * xx + yy * yy) * invR2));
    }
  }
  return sum * kWeight;
}

double pixelPsfSumOfSquares(const psf::Moffat& psf) {
  const int h = static_cast<int>(std::ceil(8.0 * psf.fwhm())) + 4;
  double sum = 0.0;
  for (int y = -h; y <= h; ++y) {
    for (int x = -h; x <= h; ++x) {
      const double p = pixelPsfValue(psf, x, y);
      sum += p * p;
    }
  }
  return sum;
}

}  // namespace st::fit

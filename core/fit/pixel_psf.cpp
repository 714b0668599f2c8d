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

PixelPsfTable::PixelPsfTable(const psf::Moffat& psf, double maxRadiusPx)
    : m_psf(psf), m_invR2(1.0 / (psf.radius * psf.radius)) {
  constexpr std::size_t kSize = std::size_t{1} << 17;
  m_sMax = maxRadiusPx * maxRadiusPx * m_invR2;
  m_scale = static_cast<double>(kSize - 1) / m_sMax;
  m_g.resize(kSize + 1);
  for (std::size_t i = 0; i <= kSize; ++i) {
    m_g[i] = std::exp(-psf.beta * std::log1p(static_cast<double>(i) / m_scale));
  }
}

double PixelPsfTable::g(double s) const noexcept {
  if (s >= m_sMax) return std::exp(-m_psf.beta * std::log1p(s));
  const double f = s * m_scale;
  const std::size_t i = static_cast<std::size_t>(f);
  const double w = f - static_cast<double>(i);
  return m_g[i] + w * (m_g[i + 1] - m_g[i]);
}

PsfSample PixelPsfTable::sample(double u, double v) const noexcept {
  PsfSample out;
  for (double sy : kSub) {
    const double yy = v + sy;
    for (double sx : kSub) {
      const double xx = u + sx;
      const double q = (xx * xx + yy * yy) * m_invR2;
      const double f = g(q);
      const double d = -2.0 * m_psf.beta * m_invR2 * f / (1.0 + q);
      out.value += f;
      out.du += d * xx;
      out.dv += d * yy;
    }
  }
  out.value *= kWeight;
  out.du *= kWeight;
  out.dv *= kWeight;
  return out;
}

double PixelPsfTable::value(double u, double v) const noexcept {
  double sum = 0.0;
  for (double sy : kSub) {
    for (double sx : kSub) {
      const double xx = u + sx;
      const double yy = v + sy;
      sum += g((xx * xx + yy * yy) * m_invR2);
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

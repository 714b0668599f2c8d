#include "st/sim/psf_stamp.hpp"

#include <algorithm>
#include <cmath>

#include "st/common/error.hpp"

namespace st::sim {

PsfStamp::PsfStamp(const psf::Moffat& psf, double trailDxPx, double trailDyPx, int radiusPx)
    : m_psf(psf), m_radius(radiusPx), m_side(2 * radiusPx + 1) {
  if (radiusPx < 1 || !(psf.radius > 0.0) || !(psf.beta > 1.0)) {
    throw InputError("simulator PSF stamp: need radius >= 1 px, Moffat R > 0 and beta > 1 (got radius " +
                     std::to_string(radiusPx) + ", R " + std::to_string(psf.radius) + ", beta " +
                     std::to_string(psf.beta) + ")");
  }
  constexpr int s = kPhases;
  const int r = radiusPx;
  // Fine samples m at offset (m + 0.5) / s px; pixel i of phase p averages m = i s - s/2 + k - p, k < s.
  const int mMin = -r * s - s / 2 - s;
  const int mMax = r * s + s / 2 - 1;
  const int n = mMax - mMin + 1;
  const double trail = std::hypot(trailDxPx, trailDyPx);
  const int steps = std::max(1, static_cast<int>(std::ceil(trail / 0.1)));
  std::vector<double> fine(static_cast<std::size_t>(n) * n);
  const double invR2 = 1.0 / (psf.radius * psf.radius);
  // Integer beta (the paper's 4): repeated multiplication instead of pow, 10x faster.
  const int integerBeta =
      psf.beta == std::round(psf.beta) && psf.beta <= 16.0 ? static_cast<int>(psf.beta) : 0;
  for (int b = 0; b < n; ++b) {
    const double v = (b + mMin + 0.5) / s;
    for (int a = 0; a < n; ++a) {
      const double u = (a + mMin + 0.5) / s;
      double sum = 0.0;
      for (int k = 0; k < steps; ++k) {
        const double f = (k + 0.5) / steps - 0.5;
        const double du = u - trailDxPx * f;
        const double dv = v - trailDyPx * f;
        const double base = 1.0 / (1.0 + (du * du + dv * dv) * invR2);
        if (integerBeta > 0) {
          double term = base;
          for (int e = 1; e < integerBeta; ++e)
            term *= base;
          sum += term;
        } else {
          sum += std::pow(base, psf.beta);
        }
      }
      fine[static_cast<std::size_t>(b) * n + a] = sum / steps;
    }
  }
  // Column sums over k first (separable box), then rows.
  m_tables.assign(static_cast<std::size_t>(s + 1) * (s + 1) * m_side * m_side, 0.0f);
  std::vector<double> boxX(static_cast<std::size_t>(n) * m_side);
  std::vector<double> tab(static_cast<std::size_t>(m_side) * m_side);
  for (int p = 0; p <= s; ++p) {
    for (int b = 0; b < n; ++b) {
      for (int i = -r; i <= r; ++i) {
        const int m0 = i * s - s / 2 - p - mMin;
        double acc = 0.0;
        for (int k = 0; k < s; ++k)
          acc += fine[static_cast<std::size_t>(b) * n + m0 + k];
        boxX[static_cast<std::size_t>(b) * m_side + (i + r)] = acc;
      }
    }
    for (int q = 0; q <= s; ++q) {
      double total = 0.0;
      for (int j = -r; j <= r; ++j) {
        const int m0 = j * s - s / 2 - q - mMin;
        for (int i = 0; i < m_side; ++i) {
          double acc = 0.0;
          for (int k = 0; k < s; ++k)
            acc += boxX[static_cast<std::size_t>(m0 + k) * m_side + i];
          tab[static_cast<std::size_t>(j + r) * m_side + i] = acc;
          total += acc;
        }
      }
      float* out = m_tables.data() + (static_cast<std::size_t>(q) * (s + 1) + p) * m_side * m_side;
      for (std::size_t k = 0; k < tab.size(); ++k)
        out[k] = static_cast<float>(tab[k] / total);
    }
  }
  m_peak = table(0, 0)[static_cast<std::size_t>(r) * m_side + r];
}

void PsfStamp::add(double* image, int width, int height, double x, double y, double photons,
                   int radius) const {
  forEach(x, y, radius, [&](int ix, int iy, double w) {
    if (ix >= 0 && iy >= 0 && ix < width && iy < height)
      image[static_cast<std::size_t>(iy) * width + ix] += photons * w;
  });
}

int PsfStamp::radiusFor(double photons, double floorPhotons) const {
  const double norm = 1.0 / m_psf.integral();
  for (int r = 1; r < m_radius; ++r) {
    if (photons * norm * m_psf(r, 0.0) < floorPhotons) return r;
  }
  return m_radius;
}

}  // namespace st::sim

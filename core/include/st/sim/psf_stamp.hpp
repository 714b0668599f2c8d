#pragma once
// A Moffat PSF integrated over pixels and averaged along a trail, tabulated at sub-pixel phases, so that a
// source can be drawn anywhere with exact total flux at the cost of a few multiply-adds per pixel.
#include <cmath>
#include <cstddef>
#include <vector>

#include "st/psf/moffat.hpp"

namespace st::sim {

class PsfStamp {
 public:
  /// Phases per pixel of the table (and the oversampling of the pixel integration, midpoint rule).
  static constexpr int kPhases = 8;

  /// Tabulates `psf` (unit total flux) over pixel offsets [-radiusPx, radiusPx] for a source whose centre
  /// moves uniformly by (trailDxPx, trailDyPx) over the exposure (centred on its mid-exposure position;
  /// sub-steps of <= 0.1 px). Each phase table is normalised to unit sum over the stamp, so the flux drawn
  /// is exact up to clipping at the image edge.
  PsfStamp(const psf::Moffat& psf, double trailDxPx, double trailDyPx, int radiusPx);

  [[nodiscard]] int radius() const noexcept { return m_radius; }

  /// Calls f(ix, iy, weight) for every stamp pixel within `radius` (<= radius()) of the pixel holding the
  /// source centred at (x, y) (0-based, centres at integers); weights sum to 1 over the full stamp. The
  /// weights interpolate bilinearly between the tabulated phases, so the centroid moves linearly with x, y.
  template <class F>
  void forEach(double x, double y, int radius, F&& f) const;

  /// Adds `photons` times the stamp at (x, y) into a width x height row-major image, clipped at the edges.
  void add(double* image, int width, int height, double x, double y, double photons, int radius) const;

  /// Largest stamp pixel value (phase 0): the peak fraction of the flux in one pixel.
  [[nodiscard]] double peakFraction() const noexcept { return m_peak; }

  /// Smallest radius at which `photons` times the Moffat's pixel value drops below `floorPhotons`.
  [[nodiscard]] int radiusFor(double photons, double floorPhotons) const;

 private:
  [[nodiscard]] const float* table(int px, int py) const noexcept {
    return m_tables.data() + (static_cast<std::size_t>(py) * (kPhases + 1) + px) * m_side * m_side;
  }
  psf::Moffat m_psf;
  int m_radius = 0;
  int m_side = 0;
  double m_peak = 0.0;
  std::vector<float> m_tables;  // (kPhases+1)^2 tables of side^2 values
};

template <class F>
void PsfStamp::forEach(double x, double y, int radius, F&& f) const {
  const double fxAll = std::floor(x);
  const double fyAll = std::floor(y);
  const int ix = static_cast<int>(fxAll);
  const int iy = static_cast<int>(fyAll);
  const double px = (x - fxAll) * kPhases;
  const double py = (y - fyAll) * kPhases;
  int p0 = static_cast<int>(px);
  int q0 = static_cast<int>(py);
  if (p0 >= kPhases) p0 = kPhases - 1;
  if (q0 >= kPhases) q0 = kPhases - 1;
  const double ax = px - p0;
  const double ay = py - q0;
  const double w00 = (1 - ax) * (1 - ay), w10 = ax * (1 - ay), w01 = (1 - ax) * ay, w11 = ax * ay;
  const float* t00 = table(p0, q0);
  const float* t10 = table(p0 + 1, q0);
  const float* t01 = table(p0, q0 + 1);
  const float* t11 = table(p0 + 1, q0 + 1);
  if (radius > m_radius) radius = m_radius;
  for (int j = -radius; j <= radius; ++j) {
    const std::size_t row = static_cast<std::size_t>(j + m_radius) * m_side + m_radius;
    for (int i = -radius; i <= radius; ++i) {
      const std::size_t k = row + i;
      f(ix + i, iy + j, w00 * t00[k] + w10 * t10[k] + w01 * t01[k] + w11 * t11[k]);
    }
  }
}

}  // namespace st::sim

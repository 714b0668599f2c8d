#pragma once
// Internal to core/sim: draws one frame of a planned scene (expected photons, then the detector).
#include <cstdint>
#include <vector>

#include "scene.hpp"
#include "st/sim/psf_stamp.hpp"
#include "st/sim/samplers.hpp"

namespace st::sim::detail {

/// Radius of the star stamp table (bright stars' wings are drawn this far).
inline constexpr int kStarStampRadiusPx = 32;
/// Radius of a moving object's stamp table.
inline constexpr int kObjectStampRadiusPx = 20;
/// Sources are drawn out to where they add less than this many photons to a pixel.
inline constexpr double kStampFloorPhotons = 0.01;

class FrameRenderer {
 public:
  FrameRenderer(const SimParams& params, const Scene& scene);

  /// Expected photons per pixel of frame n before the flat: sky + stars (with spikes) + objects.
  void expectedPhotons(int n, std::vector<double>& photons) const;
  /// Turns expected photons into raw ADU (flat, Poisson, bleed, EM gain, read noise, bias, hot pixels,
  /// cosmic rays, ADC clip) into `out` (width * height floats). `photons` is overwritten (charge).
  void detector(int n, std::vector<double>& photons, Rng& rng, float* out) const;

  [[nodiscard]] const PsfStamp& starStamp() const noexcept { return m_starStamp; }
  [[nodiscard]] const PsfStamp& objectStamp(std::size_t k) const noexcept { return m_objectStamps[k]; }
  [[nodiscard]] int starRadius(std::size_t k) const noexcept { return m_starRadius[k]; }

 private:
  void addSpikes(std::vector<double>& photons, double x, double y, double flux) const;
  const SimParams& m_p;
  const Scene& m_s;
  PsfStamp m_starStamp;
  std::vector<PsfStamp> m_objectStamps;
  std::vector<int> m_starRadius;
};

/// Spreads charge above `fullWellE` along columns (half up, half down), filling neighbours to the full
/// well; charge pushed past the top or bottom edge is lost (vertical bleed of saturated stars).
void bleedColumns(std::vector<double>& charge, int width, int height, double fullWellE);

}  // namespace st::sim::detail

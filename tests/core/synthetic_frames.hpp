#pragma once
// Small synthetic observations for the pre-processing tests (until the simulator lands): Gaussian stars
// (optionally drifting with the sky), one faint moving object, Gaussian noise, cosmic-ray hits, all with the
// truth kept.
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "st/common/frame_cube.hpp"
#include "st/common/units.hpp"

namespace st::test {

struct SynthStar {
  double x, y;  ///< at t_ref
  double peak;  ///< counts per frame at the centre
};

struct SynthHit {
  std::size_t frame;
  int x, y;
  float amplitude;
};

struct SynthScene {
  int width = 96, height = 80;
  std::size_t frames = 60;
  double cadenceS = 1.0;
  double background = 100.0;
  double sigma = 5.0;
  double fwhm = 3.0;
  Velocity skyRate;
  std::vector<SynthStar> stars;
  bool withObject = true;
  double objX = 20.0, objY = 60.0;  ///< at t_ref
  Velocity objRate{0.8, -0.3};
  double objPeak = 6.0;
  std::size_t hits = 0;  ///< cosmic rays to inject (single pixels and 2-pixel tracks)
  float hitMin = 150.0f, hitMax = 3000.0f;
  std::uint32_t seed = 1;

  std::vector<SynthHit> injected;  ///< filled by make()

  static void addGauss(float* f, int w, int h, double cx, double cy, double peak, double fwhm) {
    const double s = fwhm / 2.354820045;
    const int r = static_cast<int>(std::ceil(4 * s)) + 1;
    for (int y = static_cast<int>(cy) - r; y <= static_cast<int>(cy) + r; ++y)
      for (int x = static_cast<int>(cx) - r; x <= static_cast<int>(cx) + r; ++x) {
        if (x < 0 || y < 0 || x >= w || y >= h) continue;
        const double d2 = (x - cx) * (x - cx) + (y - cy) * (y - cy);
        f[y * w + x] += static_cast<float>(peak * std::exp(-0.5 * d2 / (s * s)));
      }
  }

  /// Object centre in frame n.
  [[nodiscard]] std::pair<double, double> objectAt(double dt) const {
    return {objX + objRate.vx * dt, objY + objRate.vy * dt};
  }

  FrameCube make() {
    FrameCube cube(width, height, frames);
    std::mt19937 rng(seed);
    std::normal_distribution<float> noise(0.0f, static_cast<float>(sigma));
    for (std::size_t n = 0; n < frames; ++n) {
      cube.info()[n].mjdMid = 60000.0 + n * cadenceS / kSecondsPerDay;
      cube.info()[n].exposureS = cadenceS;
    }
    const auto dt = cube.timeOffsetsS();
    for (std::size_t n = 0; n < frames; ++n) {
      float* f = cube.frame(n);
      for (std::size_t i = 0; i < cube.framePixels(); ++i)
        f[i] = static_cast<float>(background) + noise(rng);
      for (const auto& s : stars)
        addGauss(f, width, height, s.x + skyRate.vx * dt[n], s.y + skyRate.vy * dt[n], s.peak, fwhm);
      if (withObject) {
        const auto [ox, oy] = objectAt(dt[n]);
        addGauss(f, width, height, ox, oy, objPeak, fwhm);
      }
    }
    std::uniform_int_distribution<std::size_t> pickFrame(0, frames - 1);
    std::uniform_int_distribution<int> pickX(0, width - 1), pickY(0, height - 1);
    std::uniform_real_distribution<float> amp(hitMin, hitMax);
    for (std::size_t k = 0; k < hits; ++k) {
      const SynthHit hit{pickFrame(rng), pickX(rng), pickY(rng), amp(rng)};
      cube.frame(hit.frame)[hit.y * width + hit.x] += hit.amplitude;
      injected.push_back(hit);
      if (k % 3 == 0 && hit.x + 1 < width) {  // a short track
        const SynthHit tail{hit.frame, hit.x + 1, hit.y, 0.5f * hit.amplitude};
        cube.frame(tail.frame)[tail.y * width + tail.x] += tail.amplitude;
        injected.push_back(tail);
      }
    }
    return cube;
  }
};

}  // namespace st::test

#pragma once
// Cubes for the search tests: white noise, non-uniform frame times, an injected moving Moffat source
// matched-filtered the way pre-processing does it (convolution with the PSF), all in memory.
#include <cmath>
#include <random>
#include <vector>

#include "st/common/frame_cube.hpp"
#include "st/psf/moffat.hpp"
#include "st/search/types.hpp"

namespace st::test {

/// `frames` frames of w x h white Gaussian noise of sigma `sigma`, mid-times t0 + offsets given (seconds).
inline FrameCube noiseCube(int w, int h, const std::vector<double>& timesS, double sigma, unsigned seed) {
  FrameCube cube(w, h, timesS.size());
  std::mt19937_64 rng(seed);
  std::normal_distribution<float> noise(0.0f, static_cast<float>(sigma));
  for (auto& p : cube.pixels())
    p = noise(rng);
  for (std::size_t n = 0; n < timesS.size(); ++n) {
    cube.info()[n].mjdMid = 60000.0 + timesS[n] / 86400.0;
    cube.info()[n].exposureS = 0.05;
  }
  return cube;
}

/// Frame times: `frames` frames at a nominal cadence with random jitter and one gap, so nothing assumes
/// even spacing; sorted unless `shuffle`.
inline std::vector<double> unevenTimes(std::size_t frames, double cadenceS, unsigned seed,
                                       bool shuffle = false) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> jitter(-0.3 * cadenceS, 0.3 * cadenceS);
  std::vector<double> t(frames);
  for (std::size_t n = 0; n < frames; ++n)
    t[n] = cadenceS * static_cast<double>(n) + jitter(rng);
  for (std::size_t n = frames / 2; n < frames; ++n)
    t[n] += 3.0 * cadenceS;  // a gap mid-way
  if (shuffle) std::shuffle(t.begin(), t.end(), rng);
  return t;
}

/// Adds alpha * P(x - x(t), y - y(t)) to every frame, the source at (x0, y0) at t_ref moving at v px/s.
inline void injectMoffat(FrameCube& cube, const psf::Moffat& psf, double alpha, double x0, double y0,
                         Velocity v) {
  const std::vector<double> dt = cube.timeOffsetsS();
  const int r = static_cast<int>(std::ceil(4.0 * psf.fwhm()));
  for (std::size_t n = 0; n < cube.frameCount(); ++n) {
    const double xc = x0 + v.vx * dt[n];
    const double yc = y0 + v.vy * dt[n];
    for (int y = static_cast<int>(yc) - r; y <= static_cast<int>(yc) + r; ++y) {
      for (int x = static_cast<int>(xc) - r; x <= static_cast<int>(xc) + r; ++x) {
        if (x < 0 || y < 0 || x >= cube.width() || y >= cube.height()) continue;
        cube.frame(n)[static_cast<std::size_t>(y) * cube.width() + x] +=
            static_cast<float>(alpha * psf(x - xc, y - yc));
      }
    }
  }
}

/// The matched filter: every frame convolved with the PSF sampled on a (2r+1)^2 stamp, zero outside.
inline void matchedFilter(FrameCube& cube, const psf::Moffat& psf, int r) {
  const int w = cube.width();
  const int h = cube.height();
  std::vector<float> out(static_cast<std::size_t>(w) * h);
  std::vector<double> stamp;
  for (int dy = -r; dy <= r; ++dy) {
    for (int dx = -r; dx <= r; ++dx)
      stamp.push_back(psf(dx, dy));
  }
  for (std::size_t n = 0; n < cube.frameCount(); ++n) {
    float* f = cube.frame(n);
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        double s = 0.0;
        for (int dy = -r; dy <= r; ++dy) {
          for (int dx = -r; dx <= r; ++dx) {
            const int xx = x + dx;
            const int yy = y + dy;
            if (xx < 0 || yy < 0 || xx >= w || yy >= h) continue;
            s += stamp[static_cast<std::size_t>((dy + r) * (2 * r + 1) + dx + r)] *
                 f[static_cast<std::size_t>(yy) * w + xx];
          }
        }
        out[static_cast<std::size_t>(y) * w + x] = static_cast<float>(s);
      }
    }
    std::copy(out.begin(), out.end(), f);
  }
}

/// Sum of P^2 over the same stamp (the variance gain of the matched filter for white noise).
inline double sumP2(const psf::Moffat& psf, int r) {
  double s = 0.0;
  for (int dy = -r; dy <= r; ++dy) {
    for (int dx = -r; dx <= r; ++dx)
      s += psf(dx, dy) * psf(dx, dy);
  }
  return s;
}

/// The best result within `radius` px of (x, y), movers and static sources alike: an object injected at a
/// velocity within one FWHM over the span of the sky rate (0 in these cubes) is set aside as static by the
/// search (SearchResult::staticSources), and is still found.
inline const search::Candidate* nearestFound(const search::SearchResult& r, double x, double y, int radius) {
  const search::Candidate* best = nullptr;
  for (const auto* list : {&r.candidates, &r.staticSources})
    for (const search::Candidate& c : *list)
      if (std::abs(c.x - x) <= radius && std::abs(c.y - y) <= radius && (!best || c.snr > best->snr)) best = &c;
  return best;
}

}  // namespace st::test

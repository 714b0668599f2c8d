#pragma once
// Simulated dithers for registration tests: whole frames shifted by integer pixels (the star field moves, as
// when the telescope is re-pointed between exposures), the uncovered pixels masked.
#include <cstdint>
#include <random>
#include <utility>
#include <vector>

#include "st/common/frame_cube.hpp"

namespace st::test {

/// Integer dithers: d[0] = (0, 0) (the reference frame keeps its place, and the WCS its meaning), the others
/// uniform in [-maxPx, maxPx] per axis, plus `jump` from frame n / 2 on (a re-pointing halfway).
inline std::vector<std::pair<int, int>> randomDithers(std::size_t n, int maxPx, std::pair<int, int> jump,
                                                      std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> u(-maxPx, maxPx);
  std::vector<std::pair<int, int>> d(n, {0, 0});
  for (std::size_t k = 1; k < n; ++k) {
    d[k] = {u(rng), u(rng)};
    if (k >= n / 2) d[k] = {d[k].first + jump.first, d[k].second + jump.second};
  }
  return d;
}

/// Moves the content of frame n by d[n] (a star at p goes to p + d[n]); pixels with no source are 0 and
/// masked.
inline void ditherFrames(FrameCube& cube, const std::vector<std::pair<int, int>>& d) {
  const int w = cube.width(), h = cube.height();
  const std::size_t np = cube.framePixels();
  if (cube.mask().empty()) cube.mask().assign(np * cube.frameCount(), 0);
  std::vector<float> pix(np);
  std::vector<std::uint8_t> msk(np);
  for (std::size_t n = 0; n < cube.frameCount(); ++n) {
    float* f = cube.frame(n);
    std::uint8_t* m = cube.mask().data() + n * np;
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        const int sx = x - d[n].first, sy = y - d[n].second;
        const std::size_t i = static_cast<std::size_t>(y) * w + x;
        const bool in = sx >= 0 && sy >= 0 && sx < w && sy < h;
        const std::size_t j = in ? static_cast<std::size_t>(sy) * w + sx : 0;
        pix[i] = in ? f[j] : 0.0f;
        msk[i] = in ? m[j] : 1;
      }
    }
    std::copy(pix.begin(), pix.end(), f);
    std::copy(msk.begin(), msk.end(), m);
  }
}

}  // namespace st::test

#pragma once
// Pre-processing tests: how many pixels of a simulated moving object's track a stage zeroed.
#include <cmath>
#include <cstdint>
#include <set>
#include <utility>
#include <vector>

#include "st/common/frame_cube.hpp"
#include "st/sim/truth.hpp"

namespace st::test {

/// Over every frame, the 3 x 3 pixels around `object`'s track (rounded position at t_n) inside the frame
/// and not in `skip` (flat sample indices n * w * h + y * w + x, e.g. cosmic-ray hits): how many there
/// are, and how many of them are 0 in `frames`.
inline std::pair<std::size_t, std::size_t> zeroedAlongTrack(const FrameCube& frames,
                                                            const sim::TruthObject& object,
                                                            const std::set<std::uint64_t>& skip) {
  const int w = frames.width();
  const int h = frames.height();
  const std::uint64_t np = static_cast<std::uint64_t>(w) * h;
  const std::vector<double> dt = frames.timeOffsetsS();
  std::size_t pixels = 0, zeroed = 0;
  for (std::size_t n = 0; n < frames.frameCount(); ++n) {
    const int x = static_cast<int>(std::lround(object.xRefPx + object.vxPxPerS * dt[n]));
    const int y = static_cast<int>(std::lround(object.yRefPx + object.vyPxPerS * dt[n]));
    for (int yy = y - 1; yy <= y + 1; ++yy)
      for (int xx = x - 1; xx <= x + 1; ++xx) {
        if (xx < 0 || yy < 0 || xx >= w || yy >= h) continue;
        const std::uint64_t q = n * np + static_cast<std::uint64_t>(yy) * w + xx;
        if (skip.count(q)) continue;
        ++pixels;
        zeroed += frames.pixels()[q] == 0.0f;
      }
  }
  return {pixels, zeroed};
}

}  // namespace st::test

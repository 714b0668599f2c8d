// Exported FITS stacks are useful in DS9 (issue 18 §6): coverage-normalised (mean per contributing frame),
// background-subtracted (a gradient across the frame removed), the source kept, uncovered pixels NaN.
#include <gtest/gtest.h>

#include <cmath>

#include "st/report/fits_stack.hpp"

namespace st::report {
namespace {

TEST(StackExport, GradientRemovedSourceKeptUncoveredNaN) {
  const int w = 128, h = 96;
  Image sum(w, h);
  std::vector<std::uint16_t> coverage(sum.size(), 500);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * w + x;
      if (x < 10) coverage[i] = 250;  // the track left the frame for half the frames here
      if (y < 4) coverage[i] = 0;     // never covered (masked)
      // Per frame: background 520 -> 1040 across the frame (the demo's sums 260k-522k over 500 frames).
      const double perFrame = 520.0 + 520.0 * x / (w - 1.0) + ((x == 64 && y == 48) ? 5.2 : 0.0);
      sum.pixels[i] = static_cast<float>(perFrame * coverage[i]);
    }
  const Image out = backgroundSubtractedMean(sum, coverage);
  ASSERT_EQ(out.width, w);
  // The source stands out at its per-frame amplitude (5.2 counts) within 2%.
  EXPECT_NEAR(out.at(64, 48), 5.2, 0.01);
  // The background is gone everywhere, edges included (the mesh interpolation is exact for a gradient; 0.01
  // counts of float rounding on a 1040-count level).
  for (int y = 4; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      if (x == 64 && y == 48) continue;
      ASSERT_LT(std::abs(out.at(x, y)), 0.01) << x << "," << y;
    }
  // Uncovered rows are NaN.
  for (int x = 0; x < w; ++x)
    ASSERT_TRUE(std::isnan(out.at(x, 0))) << x;
}

}  // namespace
}  // namespace st::report

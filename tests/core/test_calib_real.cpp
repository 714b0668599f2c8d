// Calibration on the real Lowell 42-inch bias and flat frames (../shared/data/real/lowell42-5945; skipped
// when absent): masters are finite, the flat is normalised with its unusable pixels counted, science frames
// come out trimmed to TRIMSEC with no NaN and a positive sky.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "st/calib/calibration.hpp"
#include "st/io/fits_reader.hpp"
#include "test_support.hpp"

namespace st::calib {
namespace {

std::vector<std::string> filesIn(const std::filesystem::path& dir, std::size_t max = 100) {
  std::vector<std::string> out;
  for (const auto& e : std::filesystem::directory_iterator(dir))
    out.push_back(e.path().string());
  std::sort(out.begin(), out.end());
  if (out.size() > max) out.resize(max);
  return out;
}

TEST(CalibrationReal, LowellBiasAndFlat) {
  const auto root = test::realDataDir();
  if (root.empty() || !std::filesystem::is_directory(root / "lowell42-5945")) GTEST_SKIP() << "no real data";
  const auto dir = root / "lowell42-5945";
  const FrameCube bias = io::loadFrames(filesIn(dir / "bias"));
  const FrameCube flat = io::loadFrames(filesIn(dir / "flat"));
  FrameCube sci = io::loadFrames(filesIn(dir / "science", 2));
  ASSERT_EQ(bias.frameCount(), 5u);
  ASSERT_EQ(flat.frameCount(), 3u);
  NullProgress p;
  CancelToken c;
  const MasterCalibration m = buildMasters(bias, FrameCube(), flat, sci, {}, p, c);
  ASSERT_TRUE(m.biasSec.has_value());
  ASSERT_TRUE(m.trimSec.has_value());
  EXPECT_EQ(*m.biasSec, (Section{1387, 0, 45, 1370}));  // BIASSEC [1388:1432,1:1370]
  EXPECT_EQ(*m.trimSec, (Section{17, 0, 1365, 1370}));  // TRIMSEC [18:1382,1:1370]
  // After overscan subtraction the bias residual in the data area is a few counts at most.
  std::vector<float> b;
  for (int y = 0; y < 1370; ++y)
    for (int x = 17; x < 1382; ++x)
      b.push_back(m.bias.at(x, y));
  std::nth_element(b.begin(), b.begin() + b.size() / 2, b.end());
  EXPECT_LT(std::abs(b[b.size() / 2]), 20.0f);
  // The flat is normalised to median 1 inside TRIMSEC and is finite and positive everywhere.
  std::vector<float> f;
  for (int y = 0; y < 1370; ++y)
    for (int x = 17; x < 1382; ++x)
      f.push_back(m.flat.at(x, y));
  std::nth_element(f.begin(), f.begin() + f.size() / 2, f.end());
  EXPECT_NEAR(f[f.size() / 2], 1.0, 0.01);
  for (float v : m.flat.pixels)
    ASSERT_TRUE(std::isfinite(v) && v > 0.0f);
  const double nData = 1365.0 * 1370.0;
  // This flat is vignetted to ~0.3 in the corners; below flatLow (0.2) only the far corners (~1.3%) are
  // masked.
  EXPECT_LT(static_cast<double>(m.flatNonPositive + m.flatOutliers), 0.03 * nData);
  EXPECT_LT(static_cast<double>(m.hotPixels), 0.001 * nData);
  for (std::size_t i = 0; i < m.bad.size(); ++i) {
    if (!m.bad[i]) continue;
    const double dx = static_cast<double>(i % 1432) - 700.0, dy = static_cast<double>(i / 1432) - 685.0;
    ASSERT_GT(std::hypot(dx, dy), 500.0) << "masked flat pixel far from the vignetted corners";
  }

  const CalibrationReport rep = applyCalibration(sci, m, {}, p, c);
  EXPECT_EQ(sci.width(), 1365);
  EXPECT_EQ(sci.height(), 1370);
  ASSERT_EQ(rep.overscanLevel.size(), 2u);
  EXPECT_GT(rep.overscanLevel[0], 100.0f);
  std::vector<float> sky;
  for (std::size_t i = 0; i < sci.framePixels(); ++i) {
    ASSERT_TRUE(std::isfinite(sci.frame(0)[i]));
    if (!sci.isMasked(0, static_cast<int>(i % 1365), static_cast<int>(i / 1365)))
      sky.push_back(sci.frame(0)[i]);
  }
  std::nth_element(sky.begin(), sky.begin() + sky.size() / 2, sky.end());
  EXPECT_GT(sky[sky.size() / 2], 10.0f);  // 300 s of sky in VR
  if (sci.wcs) {
    // The WCS follows the trim: CRPIX1 moved by the 17 prescan columns.
    EXPECT_TRUE(sci.header.has("CRPIX1"));
  }
}

}  // namespace
}  // namespace st::calib

// Calibration: sections, masters and their application against the known truth of synthetic frames, and the
// bad-input messages of issue 3 item 9.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>

#include "st/calib/calibration.hpp"
#include "st/calib/section.hpp"
#include "st/common/error.hpp"

namespace st::calib {
namespace {

TEST(Section, MustFitTheFrame) {
  EXPECT_EQ(io::parseSection("[18:1382,1:1370]", "TRIMSEC"), (Section{17, 0, 1365, 1370}));
  try {
    checkSectionInside({10, 0, 10, 5}, 15, 5, "TRIMSEC");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("TRIMSEC [11:20,1:5]"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("15x5"), std::string::npos) << e.what();
  }
  EXPECT_NO_THROW(checkSectionInside({5, 0, 10, 5}, 15, 5, "TRIMSEC"));
}

// Truth for the synthetic detector: a bias pattern, a per-frame overscan offset, a flat, a flat sky.
struct Detector {
  int w = 40, h = 30;
  int dataW = 34;  // columns 34..39 are overscan ([35:40,1:30]), TRIMSEC [1:34,1:30]
  float bias(int x, int y) const { return 300.0f + 0.3f * x - 0.2f * y + ((x * 7 + y * 3) % 5); }
  float flat(int x, int y) const { return 0.9f + 0.2f * static_cast<float>((x * 13 + y * 29) % 17) / 16.0f; }
  FrameCube frames(std::size_t n, double sky, double offsetStep, std::uint32_t seed, const char* file) const {
    FrameCube c(w, h, n);
    std::mt19937 rng(seed);
    std::normal_distribution<float> noise(0.0f, 1.0f);
    for (std::size_t k = 0; k < n; ++k) {
      c.info()[k].file = file;
      c.info()[k].exposureS = 10.0;
      const float os = static_cast<float>(100.0 + offsetStep * k);
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
          const bool overscan = x >= dataW;
          c.frame(k)[y * w + x] =
              os + (overscan ? 0.0f : bias(x, y) + static_cast<float>(sky) * flat(x, y)) + 0.5f * noise(rng);
        }
    }
    c.header.setString("BIASSEC", "[35:40,1:30]");
    c.header.setString("TRIMSEC", "[1:34,1:30]");
    c.header.setString("CCDSUM", "2 2");
    return c;
  }
};

TEST(Calibration, RecoversSkyThroughBiasOverscanFlatAndTrim) {
  Detector d;
  FrameCube bias = d.frames(7, 0.0, 3.0, 1, "bias.fits");
  FrameCube flat = d.frames(5, 20000.0, 0.0, 2, "flat.fits");
  for (std::size_t k = 0; k < flat.frameCount(); ++k)  // twilight: flats differ in level
    for (int i = 0; i < d.w * d.h; ++i)
      if (i % d.w < d.dataW)
        flat.frame(k)[i] = 100.0f + d.bias(i % d.w, i / d.w) +
                           (flat.frame(k)[i] - 100.0f - d.bias(i % d.w, i / d.w)) * (1.0f + 0.1f * k);
  FrameCube sci = d.frames(4, 1000.0, 5.0, 3, "sci.fits");
  sci.header.setNumber("CRPIX1", 20.0);
  // One dead pixel (flat 0 -> masked, never inf) and one hot pixel in the bias.
  for (std::size_t k = 0; k < flat.frameCount(); ++k)
    flat.frame(k)[5 * d.w + 7] = 100.0f + d.bias(7, 5);
  for (std::size_t k = 0; k < bias.frameCount(); ++k)
    bias.frame(k)[9 * d.w + 11] += 500.0f;
  NullProgress p;
  CancelToken c;
  const MasterCalibration m = buildMasters(bias, FrameCube(), flat, sci, {}, p, c);
  EXPECT_EQ(m.flatNonPositive, 1u);
  EXPECT_EQ(m.hotPixels, 1u);
  const float* before = sci.pixels().data();
  const CalibrationReport rep = applyCalibration(sci, m, {}, p, c);
  EXPECT_EQ(sci.pixels().data(), before);  // trimmed in place, no second cube
  ASSERT_EQ(sci.width(), 34);
  ASSERT_EQ(sci.height(), 30);
  EXPECT_EQ(rep.badPixels, 2u);
  ASSERT_EQ(rep.overscanLevel.size(), 4u);
  EXPECT_NEAR(rep.overscanLevel[3], 115.0, 0.2);
  ASSERT_EQ(sci.mask().size(), sci.pixels().size());
  EXPECT_TRUE(sci.isMasked(0, 7, 5));
  EXPECT_TRUE(sci.isMasked(2, 11, 9));
  EXPECT_DOUBLE_EQ(*sci.header.getDouble("CRPIX1"), 20.0);  // TRIMSEC starts at column 1: no shift
  double worst = 0.0;
  for (std::size_t k = 0; k < sci.frameCount(); ++k)
    for (int y = 0; y < 30; ++y)
      for (int x = 0; x < 34; ++x) {
        const float v = sci.frame(k)[y * 34 + x];
        ASSERT_TRUE(std::isfinite(v));
        if (sci.isMasked(k, x, y)) continue;
        worst = std::max(worst, std::abs(v - 1000.0));
      }
  // Noise 0.5 counts per raw frame, flat noise ~0.5/20000 relative: 6 sigma of the residual noise.
  EXPECT_LT(worst, 4.0);
}

TEST(Calibration, SizeMismatchNamesBothSizesAndFile) {
  Detector d;
  FrameCube sci = d.frames(2, 100.0, 0.0, 4, "sci.fits");
  FrameCube small(20, 30, 2);
  small.info()[0].file = "bias_small.fits";
  NullProgress p;
  CancelToken c;
  try {
    buildMasters(small, FrameCube(), FrameCube(), sci, {}, p, c);
    FAIL();
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("20x30"), std::string::npos) << msg;
    EXPECT_NE(msg.find("40x30"), std::string::npos) << msg;
    EXPECT_NE(msg.find("bias_small.fits"), std::string::npos) << msg;
  }
}

TEST(Calibration, BinningMismatchIsRefused) {
  Detector d;
  FrameCube sci = d.frames(2, 100.0, 0.0, 5, "sci.fits");
  FrameCube bias = d.frames(3, 0.0, 0.0, 6, "bias_1x1.fits");
  bias.header.setString("CCDSUM", "1 1");
  NullProgress p;
  CancelToken c;
  try {
    buildMasters(bias, FrameCube(), FrameCube(), sci, {}, p, c);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("binning"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("bias_1x1.fits"), std::string::npos) << e.what();
  }
}

TEST(Calibration, FlatOfZerosIsAClearError) {
  Detector d;
  FrameCube sci = d.frames(2, 100.0, 0.0, 7, "sci.fits");
  FrameCube bias = d.frames(3, 0.0, 0.0, 8, "bias.fits");
  FrameCube flat = d.frames(2, 0.0, 0.0, 9, "zero_flat.fits");  // = bias: zero after subtraction
  NullProgress p;
  CancelToken c;
  try {
    buildMasters(bias, FrameCube(), flat, sci, {}, p, c);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("zero_flat.fits"), std::string::npos) << e.what();
  }
}

TEST(Calibration, DarkScalesWithExposure) {
  Detector d;
  FrameCube bias = d.frames(5, 0.0, 0.0, 10, "bias.fits");
  FrameCube dark = d.frames(5, 0.0, 0.0, 11, "dark.fits");
  for (std::size_t k = 0; k < dark.frameCount(); ++k) {
    dark.info()[k].exposureS = 100.0;
    for (int y = 0; y < d.h; ++y)
      for (int x = 0; x < d.dataW; ++x)
        dark.frame(k)[y * d.w + x] += 0.5f * 100.0f;  // 0.5 counts/s
  }
  FrameCube sci = d.frames(2, 0.0, 0.0, 12, "sci.fits");
  for (std::size_t k = 0; k < sci.frameCount(); ++k) {
    sci.info()[k].exposureS = 30.0;
    for (int y = 0; y < d.h; ++y)
      for (int x = 0; x < d.dataW; ++x)
        sci.frame(k)[y * d.w + x] += 0.5f * 30.0f;
  }
  NullProgress p;
  CancelToken c;
  const MasterCalibration m = buildMasters(bias, dark, FrameCube(), sci, {}, p, c);
  EXPECT_NEAR(m.darkPerS.at(3, 3), 0.5, 0.02);
  applyCalibration(sci, m, {}, p, c);
  double mean = 0.0;
  for (float v : sci.pixels())
    mean += v;
  EXPECT_NEAR(mean / static_cast<double>(sci.pixels().size()), 0.0, 0.1);
}

}  // namespace
}  // namespace st::calib

// Real telescope files from ../shared/data/real (skipped when absent). Expected values are from the files'
// own headers and README, and the WCS figures were cross-checked with astropy 5.2 (after unquoting the
// numbers and setting CTYPE to -TPV, which astropy needs).
#include <gtest/gtest.h>

#include <filesystem>

#include "st/common/error.hpp"
#include "st/common/units.hpp"
#include "st/io/fits_reader.hpp"
#include "st/io/fits_time.hpp"
#include "st/io/sections.hpp"
#include "st/io/wcs.hpp"
#include "test_support.hpp"

namespace st::io {
namespace {

namespace fs = std::filesystem;

TEST(IoReal, LowellScienceFrames) {
  const fs::path real = st::test::realDataDir();
  if (real.empty() || !fs::is_directory(real / "lowell42-5945" / "science")) GTEST_SKIP() << "no real data";
  const FrameCube cube = loadFrames({(real / "lowell42-5945" / "science").string()});
  ASSERT_EQ(cube.frameCount(), 15u);
  EXPECT_EQ(cube.width(), 1432);
  EXPECT_EQ(cube.height(), 1370);
  EXPECT_EQ(cube.info()[0].hdu, 2) << "fpack: the image is in HDU 2";
  // Frame 0131: DATE-OBS 2019-03-26, UTCSTART 02:53:16.35, EXPTIME 300 -> mid 02:55:46.35, which is also the
  // header's MIDTIMJD = 2458568.622064236 (a JD in an "MJD" keyword).
  EXPECT_NEAR(cube.info()[0].mjdMid, mjdFromCalendar(2019, 3, 26, 2 * 3600 + 55 * 60 + 46.35), 1e-9);
  EXPECT_NEAR(cube.info()[0].mjdMid, mjdFromMjdOrJd(*cube.header.getDouble("MIDTIMJD")), 2e-9);
  EXPECT_DOUBLE_EQ(cube.info()[0].exposureS, 300.0);
  EXPECT_NE(cube.info()[0].file.find("0131"), std::string::npos);
  EXPECT_NE(cube.info()[14].file.find("0145"), std::string::npos);
  EXPECT_NEAR(cube.timeSpanS(), 4326.25, 1.0);
  // Raw uint16 via BZERO 32768: values are non-negative integers up to 65535.
  const auto [lo, hi] = std::minmax_element(cube.pixels().begin(), cube.pixels().end());
  EXPECT_GE(*lo, 0.0f);
  EXPECT_LE(*hi, 65535.0f);
  EXPECT_GT(*hi, 60000.0f) << "saturated stars";
  // The quoted-string WCS with SCAMP PV terms is read as TPV.
  ASSERT_TRUE(cube.wcs);
  EXPECT_TRUE(cube.wcs->hasTpv());
  const auto centre = cube.wcs->pixelToSky(715.5, 684.5);
  EXPECT_NEAR(centre.raDeg, 124.61844834851694, 1e-7) << "astropy all_pix2world";
  EXPECT_NEAR(centre.decDeg, 25.328997523796684, 1e-7);
  // Plate scale from the WCS: sqrt|det CD| = 1.1074"/px. The README's 0.981"/px is the header's nominal
  // SECPIXX (= 3 x PIXSCAL 0.327); the plate solution (and astropy) give 1.107.
  ASSERT_TRUE(cube.plateScaleArcsecPerPx);
  EXPECT_NEAR(*cube.plateScaleArcsecPerPx, 1.107421716178661, 1e-6);
  EXPECT_NEAR(*cube.header.getDouble("SECPIXX"), 0.981, 1e-9);
  EXPECT_EQ(sectionFromHeader(cube.header, "TRIMSEC"), (PixelRegion{17, 0, 1365, 1370}));
  EXPECT_EQ(sectionFromHeader(cube.header, "BIASSEC"), (PixelRegion{1387, 0, 45, 1370}));
  // The asteroid's peak pixel (README: 1-based (693, 729) in frame 0131) is a local maximum.
  const float* f0 = cube.frame(0);
  const float peak = f0[728 * 1432 + 692];
  for (int dy = -2; dy <= 2; ++dy) {
    for (int dx = -2; dx <= 2; ++dx)
      EXPECT_LE(f0[(728 + dy) * 1432 + 692 + dx], peak);
  }
}

TEST(IoReal, RobustnessFilesLoadOrFailCleanly) {
  const fs::path dir = st::test::realDataDir() / "fits-robustness";
  if (st::test::realDataDir().empty() || !fs::is_directory(dir)) GTEST_SKIP() << "no real data";
  struct Expect {
    const char* file;
    int width;
    int height;
    bool wcs;
    double mjdMid;
  };
  const std::vector<Expect> expected = {
      {"panoptes_solved.fits.fz", 700, 700, true,
       mjdFromCalendar(2016, 9, 9, 8 * 3600 + 14 * 60 + 34 + 60.2)},
      {"panoptes_unsolved.fits", 700, 700, false,
       mjdFromCalendar(2016, 9, 9, 8 * 3600 + 12 * 60 + 26 + 60.2)},
      {"r20180617.060.fits", 739, 688, true, mjdFromCalendar(2018, 6, 18, 4 * 3600 + 36 * 60 + 42.01 + 60)},
      {"a8280271.fits", 536, 520, false, mjdFromCalendar(2013, 7, 13, 57 * 60 + 33 + 75.02)},
      {"ystar_saao_long_streak.fits", 512, 512, true,
       mjdFromCalendar(2002, 7, 26, 19 * 3600 + 36 * 60 + 37 + 30)},
      {"NEOS_SCI_2024239174545_cord.fits", 512, 512, true,
       mjdFromCalendar(2024, 8, 26, 17 * 3600 + 45 * 60 + 45.582 + 5.0013)},
      {"NEOS_SCI_2023311005808.fits.gz", 383, 343, true,
       mjdFromCalendar(2023, 11, 7, 58 * 60 + 8.043 + 67.0215)},
  };
  for (const auto& e : expected) {
    SCOPED_TRACE(e.file);
    const FrameCube c = loadFrames({(dir / e.file).string()});
    EXPECT_EQ(c.width(), e.width);
    EXPECT_EQ(c.height(), e.height);
    EXPECT_EQ(c.wcs != nullptr, e.wcs);
    EXPECT_NEAR(c.info()[0].mjdMid, e.mjdMid, 1e-8);
  }
  // ystar: signed int16 without BZERO keeps its negative pixels (min -401).
  const FrameCube y = loadFrames({(dir / "ystar_saao_long_streak.fits").string()});
  EXPECT_EQ(*std::min_element(y.pixels().begin(), y.pixels().end()), -401.0f);
  // panoptes: SIP; plate scale 10.32"/px (astropy: 10.319856897771974).
  const FrameCube p = loadFrames({(dir / "panoptes_solved.fits.fz").string()});
  ASSERT_TRUE(p.wcs);
  EXPECT_TRUE(p.wcs->hasSip());
  EXPECT_NEAR(*p.plateScaleArcsecPerPx, 10.319856897771974, 1e-9);
  // Every file, every HDU choice: loads or throws st::InputError, never anything else.
  for (const auto& entry : fs::directory_iterator(dir)) {
    if (entry.path().extension() == ".md") continue;
    for (const char* hdu : {"", "1", "2", "3"}) {
      LoadOptions o;
      if (*hdu != '\0') o.hdu = hdu;
      o.startMjd = 60000.0;
      o.frameRateHz = 1.0;
      NullProgress progress;
      CancelToken cancel;
      try {
        const FrameCube c = loadFrames({entry.path().string()}, o, progress, cancel);
        EXPECT_GT(c.frameCount(), 0u);
      } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find(entry.path().filename().string()), std::string::npos)
            << e.what();
      }
    }
  }
  // The three NEOSSat frames as one sequence.
  const FrameCube seq = loadFrames({(dir / "NEOS_SCI_2023311012456.fits.gz").string(),
                                    (dir / "NEOS_SCI_2023311005808.fits.gz").string(),
                                    (dir / "NEOS_SCI_2023311011346.fits.gz").string()});
  ASSERT_EQ(seq.frameCount(), 3u);
  EXPECT_NE(seq.info()[0].file.find("005808"), std::string::npos) << "sorted by time";
}

TEST(IoReal, LowellBiasAndFlatSummaries) {
  const fs::path real = st::test::realDataDir();
  if (real.empty() || !fs::is_directory(real / "lowell42-5945" / "bias")) GTEST_SKIP() << "no real data";
  const InputSummary bias = summarizeInputs({(real / "lowell42-5945" / "bias").string()});
  EXPECT_EQ(bias.frames, 5u);
  EXPECT_EQ(bias.width, 1432);
  EXPECT_EQ(bias.exposureS, 0.0);
  const InputSummary flat = summarizeInputs({(real / "lowell42-5945" / "flat").string()});
  EXPECT_EQ(flat.frames, 3u);
}

}  // namespace
}  // namespace st::io

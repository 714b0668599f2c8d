// Odd image sections are never a dead end (issue 15): a BIASSEC, TRIMSEC or DATASEC that does not fit the
// frames is clipped to them with a warning naming the file and the keyword, or ignored (with a warning)
// when nothing of it is left; a crop moves the sections with the frame; --no-overscan and
// --ignore-sections (CalibParams) overrule the headers. The measured case: a NEOSSat series cropped to
// 1078x700 stopped at "BIASSEC [1:16,1:1020] does not fit frames of 1078x700". Real NEOSSat sub-frames
// (383x343 with the full readout's sections) are checked when ../shared is present.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "st/calib/calibration.hpp"
#include "st/calib/section.hpp"
#include "st/common/error.hpp"
#include "st/io/fits_reader.hpp"
#include "st/io/sections.hpp"
#include "test_io_fixtures.hpp"
#include "test_support.hpp"

namespace st::calib {
namespace {

bool mentions(const std::vector<std::string>& warnings, const std::vector<std::string>& words) {
  for (const auto& w : warnings) {
    bool all = true;
    for (const auto& word : words)
      all = all && w.find(word) != std::string::npos;
    if (all) return true;
  }
  return false;
}

std::string joined(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v)
    s += x + "\n";
  return s;
}

TEST(SectionFit, InsideKeptPartlyOutsideClippedWhollyOutsideIgnored) {
  std::vector<std::string> w;
  EXPECT_EQ(fitSectionToFrame({0, 0, 16, 700}, 1078, 700, "BIASSEC", "a.fits", w), (Section{0, 0, 16, 700}));
  EXPECT_TRUE(w.empty());
  // The measured case: BIASSEC [1:16,1:1020] on frames of 1078x700.
  const auto clipped =
      fitSectionToFrame(io::parseSection("[1:16,1:1020]"), 1078, 700, "BIASSEC", "a.fits", w);
  ASSERT_TRUE(clipped);
  EXPECT_EQ(*clipped, (Section{0, 0, 16, 700}));
  ASSERT_EQ(w.size(), 1u);
  EXPECT_TRUE(mentions(w, {"a.fits", "BIASSEC [1:16,1:1020]", "1078x700", "clipped to [1:16,1:700]"}))
      << w[0];
  w.clear();
  EXPECT_FALSE(fitSectionToFrame(io::parseSection("[1100:1120,1:700]"), 1078, 700, "TRIMSEC", "b.fits", w));
  ASSERT_EQ(w.size(), 1u);
  EXPECT_TRUE(mentions(w, {"b.fits", "TRIMSEC [1100:1120,1:700]", "ignored"})) << w[0];
}

TEST(SectionFit, ExplicitSectionsStillMustFit) {
  EXPECT_THROW(checkSectionInside({10, 0, 10, 5}, 15, 5, "TRIMSEC"), InputError);
}

// A 40 x 30 frame whose header describes a larger readout: BIASSEC [1:4,1:100] (columns 0..3 are overscan,
// at a level of 100 + frame index), TRIMSEC [5:60,1:100] (the data, 200 counts above the overscan).
FrameCube subFramed(std::size_t frames = 3) {
  FrameCube c(40, 30, frames);
  for (std::size_t n = 0; n < frames; ++n) {
    c.info()[n].file = "neossat_sub.fits";
    c.info()[n].mjdMid = 60000.0 + static_cast<double>(n) / 86400.0;
    for (int y = 0; y < 30; ++y)
      for (int x = 0; x < 40; ++x)
        c.frame(n)[y * 40 + x] = static_cast<float>(100.0 + n + (x >= 4 ? 200.0 : 0.0));
  }
  c.header.setString("BIASSEC", "[1:4,1:100]");
  c.header.setString("TRIMSEC", "[5:60,1:100]");
  return c;
}

TEST(CalibrationSections, ClippedWithWarningsNamingFileAndKeyword) {
  FrameCube c = subFramed();
  NullProgress p;
  CancelToken t;
  CalibrationReport r;
  ASSERT_NO_THROW(r = applyCalibration(c, {}, {}, p, t));
  EXPECT_TRUE(mentions(r.warnings, {"neossat_sub.fits", "BIASSEC [1:4,1:100]", "clipped to [1:4,1:30]"}))
      << joined(r.warnings);
  EXPECT_TRUE(mentions(r.warnings, {"neossat_sub.fits", "TRIMSEC [5:60,1:100]", "clipped to [5:40,1:30]"}))
      << joined(r.warnings);
  // The clipped overscan is subtracted, the clipped trim applied.
  ASSERT_EQ(r.overscanLevel.size(), 3u);
  EXPECT_FLOAT_EQ(r.overscanLevel[2], 102.0f);
  EXPECT_EQ(c.width(), 36);
  EXPECT_EQ(c.height(), 30);
  EXPECT_FLOAT_EQ(c.frame(1)[0], 200.0f);
}

TEST(CalibrationSections, NoOverscanAndIgnoreSections) {
  NullProgress p;
  CancelToken t;
  {
    FrameCube c = subFramed();
    CalibParams params;
    params.subtractOverscan = false;  // --no-overscan
    const CalibrationReport r = applyCalibration(c, {}, params, p, t);
    EXPECT_TRUE(r.overscanLevel.empty());
    EXPECT_FALSE(mentions(r.warnings, {"BIASSEC"})) << joined(r.warnings);
    EXPECT_EQ(c.width(), 36);  // still trimmed
    EXPECT_FLOAT_EQ(c.frame(1)[0], 301.0f);
  }
  {
    FrameCube c = subFramed();
    CalibParams params;
    params.useHeaderSections = false;  // --ignore-sections
    const CalibrationReport r = applyCalibration(c, {}, params, p, t);
    EXPECT_TRUE(r.overscanLevel.empty());
    EXPECT_TRUE(r.warnings.empty()) << joined(r.warnings);
    EXPECT_EQ(c.width(), 40);
    EXPECT_FLOAT_EQ(c.frame(1)[0], 101.0f);
  }
}

TEST(CalibrationSections, NothingLeftOrMalformedIsIgnoredWithAWarning) {
  FrameCube c = subFramed();
  c.header.setString("BIASSEC", "[41:50,1:30]");  // wholly outside
  c.header.setString("TRIMSEC", "[5:40;1:30]");   // not a section
  NullProgress p;
  CancelToken t;
  const CalibrationReport r = applyCalibration(c, {}, {}, p, t);
  EXPECT_TRUE(r.overscanLevel.empty());
  EXPECT_EQ(c.width(), 40);
  EXPECT_TRUE(mentions(r.warnings, {"neossat_sub.fits", "BIASSEC [41:50,1:30]", "ignored"}))
      << joined(r.warnings);
  EXPECT_TRUE(mentions(r.warnings, {"neossat_sub.fits", "TRIMSEC", "ignored"})) << joined(r.warnings);
}

TEST(CalibrationSections, DatasecTrimsWhenThereIsNoTrimsec) {
  FrameCube c = subFramed();
  c.header.erase("TRIMSEC");
  c.header.setString("DATASEC", "[5:40,1:30]");
  NullProgress p;
  CancelToken t;
  const CalibrationReport r = applyCalibration(c, {}, {}, p, t);
  EXPECT_EQ(c.width(), 36);
  EXPECT_FALSE(c.header.has("DATASEC")) << "the trimmed frames have no data section of the old frame";
  EXPECT_FALSE(mentions(r.warnings, {"DATASEC"})) << joined(r.warnings);
}

TEST(CalibrationSections, MastersWarnToo) {
  const FrameCube bias = subFramed(5);
  const FrameCube sci = subFramed(3);
  NullProgress p;
  CancelToken t;
  MasterCalibration m;
  ASSERT_NO_THROW(m = buildMasters(bias, FrameCube(), FrameCube(), sci, {}, p, t));
  ASSERT_TRUE(m.biasSec);
  EXPECT_EQ(*m.biasSec, (Section{0, 0, 4, 30}));
  EXPECT_TRUE(mentions(m.warnings, {"neossat_sub.fits", "BIASSEC"})) << joined(m.warnings);
  EXPECT_TRUE(mentions(m.warnings, {"neossat_sub.fits", "TRIMSEC"})) << joined(m.warnings);
}

TEST(CropSections, MovedWithTheCropAndClipped) {
  FitsHeader h;
  h.setString("BIASSEC", "[1:16,1:1020]");
  h.setString("TRIMSEC", "[41:1064,1:1020]");
  h.setString("DATASEC", "[41:1064,1:1020]");
  std::vector<std::string> w;
  // Crop [1:1078,11:710]: the overscan stays at columns 1..16, rows move by 10.
  io::cropSections(h, io::parseSection("[1:1078,11:710]"), "n.fits", w);
  EXPECT_EQ(io::sectionFromHeader(h, "BIASSEC"), (io::PixelRegion{0, 0, 16, 700}));
  EXPECT_EQ(io::sectionFromHeader(h, "TRIMSEC"), (io::PixelRegion{40, 0, 1024, 700}));
  EXPECT_TRUE(mentions(w, {"n.fits", "BIASSEC [1:16,1:1020]", "clipped to [1:16,11:710]"})) << joined(w);
  w.clear();
  // A crop that leaves the overscan out drops it.
  FitsHeader h2;
  h2.setString("BIASSEC", "[1:16,1:1020]");
  io::cropSections(h2, io::parseSection("[41:400,1:300]"), "n.fits", w);
  EXPECT_FALSE(h2.has("BIASSEC"));
  EXPECT_TRUE(mentions(w, {"n.fits", "BIASSEC", "outside the crop [41:400,1:300]", "ignored"})) << joined(w);
}

// The measured case end to end: frames whose header's BIASSEC runs past the crop load, calibrate with the
// clipped overscan and warn, with no error.
TEST(CropSections, CroppedSeriesCalibratesWithWarnings) {
  test::TempDir dir;
  std::vector<std::string> files;
  for (int n = 0; n < 3; ++n) {
    test::FixtureImage img =
        test::timedFrame("2023-11-07T00:58:0" + std::to_string(n) + ".000", 0.5, 0.0, 60, 50);
    for (int y = 0; y < 50; ++y)
      for (int x = 0; x < 60; ++x)
        img.raw[static_cast<std::size_t>(y * 60 + x)] = 100.0 + n + (x >= 4 ? 200.0 : 0.0);
    img.cards.push_back({"BIASSEC", "'[1:4,1:1020]'", "overscan of the full readout"});
    img.cards.push_back({"TRIMSEC", "'[5:1064,1:1020]'", ""});
    const auto path = dir / ("f" + std::to_string(n) + ".fits");
    test::writeFixture(path, img);
    files.push_back(path.string());
  }
  io::LoadOptions o;
  o.crop = io::parseSection("[1:58,1:40]");
  NullProgress p;
  CancelToken t;
  FrameCube cube = io::loadFrames(files, o, p, t);
  EXPECT_TRUE(mentions(cube.warnings, {"f0.fits", "BIASSEC [1:4,1:1020]", "clipped"}))
      << joined(cube.warnings);
  CalibrationReport r;
  ASSERT_NO_THROW(r = applyCalibration(cube, {}, {}, p, t));
  EXPECT_TRUE(r.warnings.empty()) << joined(r.warnings);  // the loader already fitted the sections
  ASSERT_EQ(r.overscanLevel.size(), 3u);
  EXPECT_FLOAT_EQ(r.overscanLevel[1], 101.0f);
  EXPECT_EQ(cube.width(), 54);
  EXPECT_EQ(cube.height(), 40);
  EXPECT_FLOAT_EQ(cube.frame(2)[0], 200.0f);
}

// Real NEOSSat sub-frames (383 x 343) keep the full readout's BIASSEC [1:16,1:1020] and TRIMSEC
// [41:1064,1:1020]: calibration clips both and says so.
TEST(CalibrationSectionsReal, NeossatSubFrames) {
  const auto root = test::realDataDir();
  const auto file = root / "fits-robustness" / "NEOS_SCI_2023311005808.fits.gz";
  if (root.empty() || !std::filesystem::exists(file)) GTEST_SKIP() << "no real data";
  FrameCube cube = io::loadFrames({file.string()});
  ASSERT_EQ(cube.width(), 383);
  NullProgress p;
  CancelToken t;
  CalibrationReport r;
  ASSERT_NO_THROW(r = applyCalibration(cube, {}, {}, p, t));
  EXPECT_TRUE(mentions(r.warnings, {"NEOS_SCI_2023311005808", "BIASSEC [1:16,1:1020]", "383x343", "clipped"}))
      << joined(r.warnings);
  EXPECT_TRUE(mentions(r.warnings, {"NEOS_SCI_2023311005808", "TRIMSEC [41:1064,1:1020]", "clipped"}))
      << joined(r.warnings);
  EXPECT_EQ(cube.width(), 343);  // columns 41..383
  EXPECT_EQ(cube.height(), 343);
}

}  // namespace
}  // namespace st::calib

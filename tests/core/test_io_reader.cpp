// loadFrames: every BITPIX with BZERO/BSCALE/BLANK, cubes vs files, compressed inputs, HDU choice, times.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>

#include "st/common/error.hpp"
#include "st/common/units.hpp"
#include "st/io/fits_reader.hpp"
#include "st/io/fits_time.hpp"
#include "st/io/fits_writer.hpp"
#include "test_io_fixtures.hpp"
#include "test_support.hpp"

namespace st::io {
namespace {

using st::test::FixtureImage;
using st::test::TempDir;
using st::test::timedFrame;
using st::test::writeFixture;

struct BitpixCase {
  int bitpix;
  std::optional<double> bzero;
  std::optional<double> bscale;
  std::optional<long long> blank;
  std::vector<double> raw;  // 6 values; the blank one (if any) is masked
};

TEST(IoReader, EveryBitpixWithScalingAndBlankRoundTrips) {
  const std::vector<BitpixCase> cases = {
      {8, std::nullopt, std::nullopt, 255, {0, 1, 17, 200, 255, 254}},
      {8, -128.0, std::nullopt, std::nullopt, {0, 1, 127, 128, 255, 7}},  // signed bytes
      {16, std::nullopt, std::nullopt, -32768, {-32768, -401, 0, 1, 32767, 1234}},
      {16, 32768.0, 1.0, std::nullopt, {-32768, -1, 0, 1, 32767, 100}},  // unsigned 16-bit
      {16, 1000.0, 0.5, 7, {7, -3, 0, 11, 32000, -32000}},
      {32, std::nullopt, std::nullopt, -2147483647LL, {-2147483647.0, -5, 0, 70000, 2147483647.0, 16777216}},
      {32, 2147483648.0, 1.0, std::nullopt, {-2147483648.0, 0, 1, 2, 3, 4}},
      {64, std::nullopt, std::nullopt, -1, {-1, 0, 1, 123456789, -987654, 42}},
      {64, 10.0, 2.0, std::nullopt, {0, 1, 2, 3, -4, 1000000}},
      {-32, std::nullopt, std::nullopt, std::nullopt, {NAN, -1.5, 0.0, 3.25, 1e30, -7e-20}},
      {-32, 100.0, 2.0, std::nullopt, {1.0, 2.0, NAN, -4.5, 0.0, 8.0}},
      {-64, std::nullopt, std::nullopt, std::nullopt, {0.1, NAN, 65488.0, -10453.25, 1e-5, 3.0}},
  };
  TempDir dir;
  for (const auto& c : cases) {
    SCOPED_TRACE("BITPIX " + std::to_string(c.bitpix) + " BZERO " + std::to_string(c.bzero.value_or(0)));
    FixtureImage img;
    img.bitpix = c.bitpix;
    img.width = 3;
    img.height = 2;
    img.raw = c.raw;
    img.bzero = c.bzero;
    img.bscale = c.bscale;
    img.blank = c.blank;
    img.cards.push_back({"DATE-OBS", "'2024-01-02T03:04:05.5'", ""});
    img.cards.push_back({"EXPTIME", "2.0", ""});
    const auto path =
        dir / ("b" + std::to_string(c.bitpix) + "_" + std::to_string(c.bzero.value_or(0)) + ".fits");
    writeFixture(path, img);
    const FrameCube cube = loadFrames({path.string()});
    ASSERT_EQ(cube.width(), 3);
    ASSERT_EQ(cube.height(), 2);
    ASSERT_EQ(cube.frameCount(), 1u);
    for (int i = 0; i < 6; ++i) {
      const bool isNull = std::isnan(c.raw[i]) || (c.blank && c.raw[i] == static_cast<double>(*c.blank));
      const int x = i % 3;
      const int y = i / 3;
      EXPECT_EQ(cube.isMasked(0, x, y), isNull) << "pixel " << i;
      if (isNull) {
        EXPECT_EQ(cube.frame(0)[i], 0.0f) << "masked pixels are set to 0";
        continue;
      }
      const double physical = c.raw[i] * c.bscale.value_or(1.0) + c.bzero.value_or(0.0);
      EXPECT_NEAR(cube.frame(0)[i], physical, std::abs(physical) * 1e-7) << "pixel " << i;
    }
    EXPECT_NEAR(cube.info()[0].mjdMid, mjdFromCalendar(2024, 1, 2, 3 * 3600 + 4 * 60 + 5.5 + 1.0), 1e-9);
  }
}

std::vector<std::string> writeShuffledFrames(const TempDir& dir, int count) {
  std::vector<std::string> paths;
  for (int n = 0; n < count; ++n) {
    const int order = (n * (count - 1)) % count;  // files named out of time order
    char date[64];
    std::snprintf(date, sizeof date, "2023-05-06T07:08:%06.3f", 10.0 + order * 0.25);
    const auto path = dir / ("frame" + std::to_string(n) + ".fits");
    writeFixture(path, timedFrame(date, 0.2, 1000.0 * order));
    paths.push_back(path.string());
  }
  return paths;
}

TEST(IoReader, FilesCubeAndFolderGiveIdenticalCubes) {
  TempDir dir;
  std::filesystem::create_directory(dir / "frames");
  TempDir frames;
  const auto paths = writeShuffledFrames(frames, 5);
  const FrameCube fromFiles = loadFrames(paths);
  ASSERT_EQ(fromFiles.frameCount(), 5u);
  ASSERT_FALSE(fromFiles.warnings.empty());
  EXPECT_NE(fromFiles.warnings.front().find("sorted"), std::string::npos) << fromFiles.warnings.front();
  for (std::size_t n = 0; n < 5; ++n) {
    EXPECT_EQ(fromFiles.frame(n)[0], 1000.0f * static_cast<float>(n)) << "frames sorted by time";
    EXPECT_NEAR(fromFiles.info()[n].mjdMid,
                mjdFromCalendar(2023, 5, 6, 7 * 3600 + 8 * 60 + 10.0 + n * 0.25 + 0.1), 2e-11);
    EXPECT_DOUBLE_EQ(fromFiles.info()[n].exposureS, 0.2);
  }
  const FrameCube fromFolder = loadFrames({frames.path().string()});
  EXPECT_EQ(fromFolder.pixels(), fromFiles.pixels());

  const std::string cubePath = (dir / "cube.fits").string();
  writeCube(cubePath, fromFiles, provenanceCards("test"));
  const FrameCube fromCube = loadFrames({cubePath});
  ASSERT_EQ(fromCube.frameCount(), 5u);
  EXPECT_EQ(fromCube.pixels(), fromFiles.pixels());
  EXPECT_TRUE(fromCube.warnings.empty());
  for (std::size_t n = 0; n < 5; ++n) {
    EXPECT_NEAR(fromCube.info()[n].mjdMid, fromFiles.info()[n].mjdMid, 1e-12)
        << "times from the FRAMES table";
    EXPECT_DOUBLE_EQ(fromCube.info()[n].exposureS, 0.2);
    EXPECT_EQ(fromCube.info()[n].plane, static_cast<int>(n));
  }
  EXPECT_EQ(fromCube.header.getString("SOFTWARE").value_or("").rfind("synthtrack ", 0), 0u);
}

// A bias, dark or flat frame (IMAGETYP or OBSTYPE, any case and wording) or a frame of EXPTIME 0 among the
// science frames is stacked like the others: the user is told, with the file named, unless the frames are
// loaded as calibration frames.
TEST(IoReader, WarnsAboutCalibrationFramesGivenAsScience) {
  TempDir dir;
  struct Case {
    const char* name;
    const char* key;
    const char* type;  // nullptr: no type card
    double exptime;
    const char* expected;  // nullptr: no warning
  };
  const Case cases[] = {
      {"light", "IMAGETYP", "Light Frame", 0.2, nullptr},
      {"object", "OBSTYPE", "OBJECT", 0.2, nullptr},
      {"bias", "IMAGETYP", "Bias Frame", 0.2, "a bias frame"},
      {"zero", "IMAGETYP", "ZERO", 0.2, "a bias frame"},
      {"flat", "IMAGETYP", "FLAT", 0.2, "a flat frame"},
      {"flatfield", "OBSTYPE", "flat field", 0.2, "a flat frame"},
      {"dark", "OBSTYPE", "dark", 0.2, "a dark frame"},
      {"noexposure", "IMAGETYP", nullptr, 0.0, "EXPTIME = 0"},
  };
  std::vector<std::string> paths;
  for (std::size_t n = 0; n < std::size(cases); ++n) {
    char date[64];
    std::snprintf(date, sizeof date, "2023-05-06T07:08:%06.3f", 10.0 + n * 0.25);
    FixtureImage img = timedFrame(date, cases[n].exptime, 0.0);
    if (cases[n].type) img.cards.push_back({cases[n].key, std::string("'") + cases[n].type + "'", ""});
    const auto path = dir / (std::string(cases[n].name) + ".fits");
    writeFixture(path, img);
    paths.push_back(path.string());
  }
  const FrameCube cube = loadFrames(paths);
  ASSERT_EQ(cube.frameCount(), std::size(cases));
  for (std::size_t n = 0; n < std::size(cases); ++n) {
    const std::string file = "/" + std::string(cases[n].name) + ".fits";
    const auto w = std::find_if(cube.warnings.begin(), cube.warnings.end(),
                                [&](const std::string& s) { return s.find(file) != std::string::npos; });
    if (cases[n].expected == nullptr) {
      EXPECT_EQ(w, cube.warnings.end()) << cases[n].name << ": " << *w;
    } else {
      ASSERT_NE(w, cube.warnings.end()) << cases[n].name << " has no warning";
      EXPECT_NE(w->find(cases[n].expected), std::string::npos) << *w;
      EXPECT_NE(w->find("science"), std::string::npos) << *w;
    }
  }
  EXPECT_EQ(summarizeInputs(paths).warnings, cube.warnings) << "info shows the same warnings";
  LoadOptions calibration;
  calibration.scienceFrames = false;
  NullProgress progress;
  CancelToken cancel;
  EXPECT_TRUE(loadFrames(paths, calibration, progress, cancel).warnings.empty());
}

TEST(IoReader, TileCompressedAndGzipMatchPlain) {
  TempDir dir;
  FixtureImage img = timedFrame("2020-02-03T04:05:06", 1.0, 0.0, 40, 30);
  img.bitpix = 16;
  img.bzero = 32768.0;
  for (std::size_t i = 0; i < img.raw.size(); ++i)
    img.raw[i] = static_cast<double>((i * 7919) % 60000) - 30000.0;
  writeFixture(dir / "plain.fits", img);
  FixtureImage rice = img;
  rice.compress = RICE_1;
  writeFixture(dir / "rice.fits.fz", rice);
  writeFixture(dir / "whole.fits.gz", img);
  FixtureImage fl = timedFrame("2020-02-03T04:05:06", 1.0, 0.5, 40, 30);
  fl.compress = GZIP_1;
  writeFixture(dir / "float.fits.fz", fl);
  const FrameCube plain = loadFrames({(dir / "plain.fits").string()});
  const FrameCube fz = loadFrames({(dir / "rice.fits.fz").string()});
  const FrameCube gz = loadFrames({(dir / "whole.fits.gz").string()});
  EXPECT_EQ(fz.pixels(), plain.pixels());
  EXPECT_EQ(gz.pixels(), plain.pixels());
  EXPECT_EQ(fz.info()[0].hdu, 2) << "compressed image lives in extension 1 (HDU 2)";
  EXPECT_DOUBLE_EQ(fz.info()[0].mjdMid, plain.info()[0].mjdMid);
  EXPECT_EQ(plain.frame(0)[5], static_cast<float>((5 * 7919) % 60000 - 30000 + 32768));
  const FrameCube flz = loadFrames({(dir / "float.fits.fz").string()});
  EXPECT_EQ(flz.frame(0)[7], 7.5f) << "lossless float tile compression";
}

TEST(IoReader, ImageInAnyHdu) {
  TempDir dir;
  FixtureImage img = timedFrame("2020-02-03T04:05:06", 1.0, 3.0);
  img.emptyPrimary = true;
  img.extname = "SCI";
  const std::string path = (dir / "mef.fits").string();
  writeFixture(path, img);
  NullProgress progress;
  CancelToken cancel;
  EXPECT_EQ(loadFrames({path}).info()[0].hdu, 2) << "first image HDU with data";
  LoadOptions byName;
  byName.hdu = "SCI";
  EXPECT_EQ(loadFrames({path}, byName, progress, cancel).frame(0)[1], 4.0f);
  LoadOptions byNumber;
  byNumber.hdu = "2";
  EXPECT_EQ(loadFrames({path}, byNumber, progress, cancel).info()[0].hdu, 2);
  LoadOptions missing;
  missing.hdu = "7";
  try {
    (void)loadFrames({path}, missing, progress, cancel);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("HDU 7"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("mef.fits"), std::string::npos) << e.what();
  }
}

TEST(IoReader, CubeTimesFromPlaneKeywordsAndFrameRate) {
  TempDir dir;
  FixtureImage cube;
  cube.width = 2;
  cube.height = 2;
  cube.planes = 3;
  for (int i = 0; i < 12; ++i)
    cube.raw.push_back(i);
  cube.cards = {{"MJD_1", "60000.8", ""}, {"MJD_2", "2460001.1", "JD-like"}, {"MJD_3", "60000.75", ""}};
  writeFixture(dir / "keys.fits", cube);
  const FrameCube a = loadFrames({(dir / "keys.fits").string()});
  ASSERT_EQ(a.frameCount(), 3u);
  EXPECT_NEAR(a.info()[0].mjdMid, 60000.6, 1e-9) << "JD 2460001.1 in an MJD keyword = MJD 60000.6";
  EXPECT_DOUBLE_EQ(a.info()[1].mjdMid, 60000.75);
  EXPECT_DOUBLE_EQ(a.info()[2].mjdMid, 60000.8);
  EXPECT_EQ(a.frame(0)[0], 4.0f) << "plane 2 sorts first";
  EXPECT_EQ(a.frame(2)[0], 0.0f) << "plane 1 sorts last";
  EXPECT_FALSE(a.warnings.empty()) << "out-of-order planes are sorted with a warning";

  cube.cards = {
      {"DATE-OBS", "'2022-01-01T00:00:00'", ""}, {"EXPTIME", "0.05", ""}, {"FRAMERAT", "20.0", "Hz"}};
  writeFixture(dir / "rate.fits", cube);
  const FrameCube b = loadFrames({(dir / "rate.fits").string()});
  const double t0 = mjdFromCalendar(2022, 1, 1, 0.025);
  for (int n = 0; n < 3; ++n)
    EXPECT_NEAR(b.info()[n].mjdMid, t0 + n * 0.05 / kSecondsPerDay, 1e-11);

  cube.cards.clear();
  writeFixture(dir / "none.fits", cube);
  LoadOptions user;
  user.startMjd = 59000.25;
  user.frameRateHz = 2.0;
  user.exposureS = 0.4;
  NullProgress progress;
  CancelToken cancel;
  const FrameCube c = loadFrames({(dir / "none.fits").string()}, user, progress, cancel);
  EXPECT_DOUBLE_EQ(c.info()[2].mjdMid, 59000.25 + 1.0 / kSecondsPerDay);
  EXPECT_DOUBLE_EQ(c.info()[1].exposureS, 0.4);
}

struct CountingProgress final : ProgressSink {
  std::atomic<int> calls{0};
  std::atomic<double> last{0.0};
  void report(double f, std::string_view) override {
    ++calls;
    last = f;
  }
};

TEST(IoReader, ReportsProgressAndCancels) {
  TempDir dir;
  const auto paths = writeShuffledFrames(dir, 6);
  CountingProgress progress;
  CancelToken cancel;
  (void)loadFrames(paths, LoadOptions{}, progress, cancel);
  EXPECT_GE(progress.calls.load(), 6);
  EXPECT_NEAR(progress.last.load(), 1.0, 1e-12);
  cancel.cancel();
  EXPECT_THROW((void)loadFrames(paths, LoadOptions{}, progress, cancel), Cancelled);
}

TEST(IoReader, CropsFramesToACommonRegion) {
  TempDir dir;
  writeFixture(dir / "a.fits", timedFrame("2020-01-01T00:00:00", 1, 0, 6, 4));
  FixtureImage big = timedFrame("2020-01-01T00:00:01", 1, 0, 8, 5);
  big.cards.push_back({"CRPIX1", "10.0", ""});
  writeFixture(dir / "b.fits", big);
  LoadOptions o;
  o.crop = parseSection("[2:5,2:4]");
  NullProgress progress;
  CancelToken cancel;
  const FrameCube c = loadFrames({(dir / "b.fits").string(), (dir / "a.fits").string()}, o, progress, cancel);
  ASSERT_EQ(c.width(), 4);
  ASSERT_EQ(c.height(), 3);
  EXPECT_EQ(c.frame(0)[0], 1.0f + 6.0f) << "a.fits: x=1, y=1 of a 6-wide frame";
  EXPECT_EQ(c.frame(1)[0], 1.0f + 8.0f) << "b.fits: x=1, y=1 of an 8-wide frame";
}

// Crops of a plain float32 cube (the out-of-core tiles' reads, issue 20) are read straight from the file,
// full-width strips in one read and narrower rectangles row by row: the same pixels and NaN masks as the
// same region of the whole frames.
TEST(IoReader, FloatCubeCropsEqualTheWholeFramesRegion) {
  TempDir dir;
  FrameCube cube(13, 9, 3);
  for (std::size_t i = 0; i < cube.pixels().size(); ++i)
    cube.pixels()[i] = 0.25f * static_cast<float>(i) - 40.0f;
  cube.frame(1)[4 * 13 + 6] = NAN;
  for (std::size_t n = 0; n < 3; ++n) {
    cube.info()[n].mjdMid = 60000.0 + static_cast<double>(n) / 86400.0;
    cube.info()[n].exposureS = 1.0;
  }
  const std::string path = (dir / "f.fits").string();
  writeCube(path, cube);
  NullProgress progress;
  CancelToken cancel;
  const FrameCube whole = loadFrames({path}, LoadOptions{}, progress, cancel);
  ASSERT_EQ(whole.mask().size(), whole.pixels().size());
  for (const PixelRegion r : {PixelRegion{0, 3, 13, 4}, PixelRegion{5, 2, 4, 5}, PixelRegion{12, 8, 1, 1}}) {
    LoadOptions o;
    o.crop = r;
    const FrameCube c = loadFrames({path}, o, progress, cancel);
    ASSERT_EQ(c.width(), r.width);
    ASSERT_EQ(c.height(), r.height);
    ASSERT_EQ(c.frameCount(), 3u);
    const bool hasNan = r.x0 <= 6 && 6 < r.x0 + r.width && r.y0 <= 4 && 4 < r.y0 + r.height;
    ASSERT_EQ(c.mask().empty(), !hasNan) << r.x0 << "," << r.y0;
    for (std::size_t n = 0; n < 3; ++n) {
      for (int y = 0; y < r.height; ++y) {
        for (int x = 0; x < r.width; ++x) {
          const std::size_t from = n * whole.framePixels() + static_cast<std::size_t>(r.y0 + y) * 13 + r.x0 + x;
          const std::size_t to = n * c.framePixels() + static_cast<std::size_t>(y) * r.width + x;
          EXPECT_EQ(c.pixels()[to], whole.pixels()[from]) << n << " " << x << " " << y;
          if (hasNan) {
            EXPECT_EQ(c.mask()[to], whole.mask()[from]) << n << " " << x << " " << y;
          }
        }
      }
    }
  }
}

}  // namespace
}  // namespace st::io

// Injection into real frames: Lowell 42-inch, 15 x 300 s raw frames of (5945) Roachapproach
// (../shared/data/real/lowell42-5945, README there; skipped when absent), calibrated with its 5 biases and
// 3 twilight flats. 12 movers are injected with the PSF fitted on the frames' stars and Poisson noise at the
// camera's gain (AGAIN_01 = 4.95 e-/ADU; the headers have no GAIN). Oracles: the copies keep the file names
// (without .fz), the HDU number (2: the image follows an empty primary) and the header (STINJECT and
// HISTORY added); read back and calibrated with the same masters, they differ from the originals by the
// injected flux (each mover within 5%, all together within 2%; Poisson noise ~1-2% per mover), nothing
// changes in the overscan or outside the movers' stamps, and every copy is written as integers (BITPIX 16).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "st/calib/calibration.hpp"
#include "st/inject/injection.hpp"
#include "st/inject/truth_json.hpp"
#include "st/io/fits_reader.hpp"
#include "test_support.hpp"

namespace st::inject {
namespace {

TEST(InjectReal, Lowell5945CopiesReadBackWithTheInjectedSignal) {
  const auto root = test::realDataDir();
  if (root.empty() || !std::filesystem::is_directory(root / "lowell42-5945")) GTEST_SKIP() << "no real data";
  const auto dir = root / "lowell42-5945";
  const std::vector<std::string> science = test::filesIn(dir / "science");
  FrameCube raw = test::loadFiles(science, true);
  ASSERT_EQ(raw.frameCount(), 15u);
  const FrameCube bias = test::loadFiles(test::filesIn(dir / "bias"), false),
                  flat = test::loadFiles(test::filesIn(dir / "flat"), false);
  NullProgress p;
  CancelToken c;
  const calib::CalibParams cp;
  const calib::MasterCalibration masters = calib::buildMasters(bias, FrameCube{}, flat, raw, cp, p, c);
  const FrameCube original = raw;
  InjectParams params;
  params.count = 12;
  params.snrMin = 8.0;
  params.snrMax = 20.0;
  params.rateMinPxS = 0.0005;
  params.rateMaxPxS = 0.004;
  params.seed = 3;
  test::TempDir out;
  const InjectionRun run = injectIntoFiles(raw, masters, cp, {}, params, 4.95, out.path().string(), p, c);
  ASSERT_EQ(run.plan.objects.size(), 12u);
  ASSERT_EQ(run.written.size(), 15u);
  EXPECT_EQ(run.clippedPixels, 0u);
  EXPECT_TRUE(run.plan.psfMeasured);
  EXPECT_GT(run.plan.psf.fwhm(), 1.0);
  EXPECT_LT(run.plan.psf.fwhm(), 6.0);
  EXPECT_EQ(run.geometry.offsetX, 17) << "TRIMSEC [18:1382,1:1370]";
  EXPECT_TRUE(run.geometry.integerCounts);
  std::printf("PSF FWHM %.3f px beta %.2f; %zu masked pixels\n", run.plan.psf.fwhm(), run.plan.psf.beta,
              run.field.maskedPixels);
  for (std::size_t k = 0; k < science.size(); ++k)
    EXPECT_EQ(std::filesystem::path(run.written[k]).filename().string() + ".fz",
              std::filesystem::path(science[k]).filename().string());
  const nlohmann::json truth = truthToJson(run, {});
  EXPECT_EQ(truth["objects"].size(), 12u);

  const FrameCube injected = test::loadFiles(run.written, true);
  ASSERT_EQ(injected.frameCount(), 15u);
  for (std::size_t n = 0; n < injected.frameCount(); ++n) {
    EXPECT_EQ(injected.info()[n].hdu, 2) << "the image stays in HDU 2";
    EXPECT_DOUBLE_EQ(injected.info()[n].mjdMid, original.info()[n].mjdMid);
  }
  EXPECT_EQ(injected.header.getDouble("STINJECT").value_or(0), 12.0);
  EXPECT_EQ(injected.header.getDouble("BITPIX").value_or(0), 16.0);
  for (const char* key : {"OBJECT", "DATE-OBS", "UTCSTART", "TRIMSEC", "BIASSEC", "CRVAL1", "AGAIN_01"})
    EXPECT_EQ(injected.header.getString(key), original.header.getString(key)) << key;
  // Raw: the overscan and everything outside the stamps unchanged; integers stay integers.
  std::vector<std::uint8_t> inStamp(raw.framePixels(), 0);
  for (const auto& o : run.plan.objects)
    for (const auto& s : o.stamps)
      for (int y = s.y0; y < s.y0 + s.height; ++y)
        for (int x = s.x0; x < s.x0 + s.width; ++x)
          inStamp[static_cast<std::size_t>(y + run.geometry.offsetY) * raw.width() + x +
                  run.geometry.offsetX] = 1;
  std::size_t changedOutside = 0, nonInteger = 0;
  for (std::size_t n = 0; n < raw.frameCount(); ++n)
    for (std::size_t i = 0; i < raw.framePixels(); ++i) {
      const float a = injected.frame(n)[i], b = original.frame(n)[i];
      if (a != b && !inStamp[i]) ++changedOutside;
      if (a != std::round(a)) ++nonInteger;
    }
  EXPECT_EQ(changedOutside, 0u);
  EXPECT_EQ(nonInteger, 0u);
  // Calibrated: each mover's flux.
  FrameCube calIn = injected, calOut = original;
  calib::applyCalibration(calIn, masters, cp, p, c);
  calib::applyCalibration(calOut, masters, cp, p, c);
  double total = 0.0, expected = 0.0;
  for (const auto& o : run.plan.objects) {
    double sum = 0.0;
    for (std::size_t n = 0; n < calIn.frameCount(); ++n) {
      const Stamp& s = o.stamps[n];
      for (int y = s.y0; y < s.y0 + s.height; ++y)
        for (int x = s.x0; x < s.x0 + s.width; ++x) {
          const std::size_t i = static_cast<std::size_t>(y) * calIn.width() + x;
          sum += calIn.frame(n)[i] - calOut.frame(n)[i];
        }
    }
    const double perFrame = sum / static_cast<double>(calIn.frameCount());
    std::printf("mover %2d: flux %.1f, measured %.1f counts/frame, expected SNR %.2f\n", o.id, o.flux,
                perFrame, o.expectedSnr);
    EXPECT_NEAR(perFrame / o.flux, 1.0, 0.05) << "mover " << o.id;
    total += perFrame;
    expected += o.flux;
  }
  EXPECT_NEAR(total / expected, 1.0, 0.02);
}

}  // namespace
}  // namespace st::inject

// Plate solving a real frame (issue 15 item 5): a shared Lowell 42" frame of 5945 (1432 x 1370 px at
// 1.1074 arcsec/px, 26' x 25', SCAMP TPV WCS fitted on Gaia) loaded with its WCS keywords removed is solved
// by astrometry.net from the sources found in it; the oracle is the header's own WCS. Tolerances: 1 arcsec
// at the centre (issue 15), 3 arcsec at the corners (measured 2026-11-27: 0.34-0.67 arcsec at the centre of
// all 15 frames, corners 0.09-2.9 arcsec: the solution rests on the 5-6 saturated Tycho-2 stars of the
// field and fits no distortion). Skips when solve-field, the index files or ../shared are absent.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>

#include "st/astro/plate_solve.hpp"
#include "st/common/error.hpp"
#include "st/io/fits_reader.hpp"
#include "st/io/wcs.hpp"
#include "st/pipeline/plate_solve_stage.hpp"
#include "test_support.hpp"

namespace st {
namespace {

bool onPath(const std::string& program) {
  std::stringstream dirs(std::getenv("PATH") != nullptr ? std::getenv("PATH") : "");
  for (std::string d; std::getline(dirs, d, ':');)
    if (std::filesystem::exists(std::filesystem::path(d) / program)) return true;
  return false;
}

double separationArcsec(const Wcs::Sky& a, const Wcs::Sky& b) {
  constexpr double d = M_PI / 180.0;
  const double s = std::sin(a.decDeg * d) * std::sin(b.decDeg * d) +
                   std::cos(a.decDeg * d) * std::cos(b.decDeg * d) * std::cos((a.raDeg - b.raDeg) * d);
  return std::acos(std::clamp(s, -1.0, 1.0)) / d * 3600.0;
}

TEST(PlateSolveReal, LowellFrameWithoutWcsAgreesWithItsHeaderWcs) {
  const auto data = test::realDataDir();
  const auto file = data / "lowell42-5945" / "science" / "20190326.0131.fits.fz";
  if (data.empty() || !std::filesystem::exists(file)) GTEST_SKIP() << "no shared Lowell frames";
  if (!onPath("solve-field")) GTEST_SKIP() << "astrometry.net's solve-field is not installed";
  if (astro::findIndexFiles(astro::configIndexDirs("/etc/astrometry.cfg")).empty())
    GTEST_SKIP() << "no astrometry.net index files (astrometry-data-tycho2-07-littleendian)";

  FrameCube cube = io::loadFrames({file.string()});
  ASSERT_TRUE(cube.wcs) << "the shared frame should have a header WCS (the oracle)";
  const std::shared_ptr<const Wcs> truth = cube.wcs;
  // The frame as it would come without a WCS: no WCS object, no plate scale, no WCS cards.
  cube.wcs.reset();
  cube.plateScaleArcsecPerPx.reset();
  std::vector<FitsCard> kept;
  for (const auto& c : cube.header.cards)
    if (!Wcs::isWcsKeyword(c.key)) kept.push_back(c);
  cube.header.cards = kept;
  ASSERT_FALSE(Wcs::fromHeader(cube.header, nullptr));

  NullProgress progress;
  CancelToken cancel;
  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<io::XyStar> stars = pipeline::frameStars(cube, progress, cancel);
  astro::PlateSolveParams params;  // hints from the header: SECPIXX 0.981 (11% off), RA/DEC of the telescope
  params.timeLimitS = 180.0;
  const astro::PlateSolution s = pipeline::plateSolveCube(cube, stars, params, progress, cancel);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_TRUE(cube.wcs);
  EXPECT_EQ(cube.wcs, s.wcs);

  const double w = cube.width() - 1.0, h = cube.height() - 1.0;
  const double centre =
      separationArcsec(truth->pixelToSky(0.5 * w, 0.5 * h), s.wcs->pixelToSky(0.5 * w, 0.5 * h));
  double worstCorner = 0.0;
  std::string corners;
  for (const auto& [x, y] : {std::pair{0.0, 0.0}, {w, 0.0}, {0.0, h}, {w, h}}) {
    const double d = separationArcsec(truth->pixelToSky(x, y), s.wcs->pixelToSky(x, y));
    worstCorner = std::max(worstCorner, d);
    corners += ' ';  // not " " + std::to_string(d): GCC 12 warns (-Wrestrict) on that wrongly
    corners += std::to_string(d);
  }
  std::printf(
      "plate solve of %s: %zu sources, %s, %.1f s; header WCS vs solution: centre %.3f arcsec, corners%s "
      "arcsec; scale %.5f vs %.5f arcsec/px\n",
      file.filename().c_str(), stars.size(), s.method.c_str(), seconds, centre, corners.c_str(),
      s.scaleArcsecPerPx, truth->plateScaleArcsecPerPx());
  EXPECT_LT(centre, 1.0);
  EXPECT_LT(worstCorner, 3.0);
  EXPECT_NEAR(s.scaleArcsecPerPx / truth->plateScaleArcsecPerPx(), 1.0, 0.003);
  EXPECT_NEAR(*cube.plateScaleArcsecPerPx, s.scaleArcsecPerPx, 1e-12);
}

}  // namespace
}  // namespace st

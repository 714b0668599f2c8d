// A simulated observation survives the trip through FITS: what `synthtrack-cli simulate` writes, the reader
// loads with identical pixels, the same frame times, the TAN WCS and the plate scale.
#include <gtest/gtest.h>

#include <cmath>

#include "st/io/fits_reader.hpp"
#include "st/io/fits_writer.hpp"
#include "st/io/wcs.hpp"
#include "st/sim/simulator.hpp"
#include "test_support.hpp"

TEST(SimFits, CubeRoundTripKeepsPixelsTimesAndWcs) {
  st::sim::SimParams p = st::sim::preset("small");
  p.frames = 12;
  st::NullProgress progress;
  st::CancelToken cancel;
  const auto r = st::sim::simulate(p, 17, progress, cancel);
  st::test::TempDir dir;
  const std::string path = (dir / "small.fits").string();
  st::io::writeCube(path, r.cube);
  const st::FrameCube back = st::io::loadFrames({path});
  ASSERT_EQ(back.frameCount(), r.cube.frameCount());
  ASSERT_EQ(back.width(), p.width);
  ASSERT_EQ(back.height(), p.height);
  EXPECT_EQ(back.pixels(), r.cube.pixels());
  for (std::size_t n = 0; n < back.frameCount(); ++n) {
    EXPECT_NEAR((back.info()[n].mjdMid - r.cube.info()[n].mjdMid) * 86400.0, 0.0, 1e-5) << "frame " << n;
    EXPECT_NEAR(back.info()[n].exposureS, p.exposureS, 1e-9);
  }
  ASSERT_TRUE(back.wcs);
  EXPECT_NEAR(back.plateScaleArcsecPerPx.value_or(0.0), 0.305, 1e-6);
  // The reference pixel (the frame centre, 0-based) is at CRVAL.
  const auto sky = back.wcs->pixelToSky(0.5 * (p.width - 1), 0.5 * (p.height - 1));
  EXPECT_NEAR(sky.raDeg, p.raDeg, 1e-9);
  EXPECT_NEAR(sky.decDeg, p.decDeg, 1e-9);
  EXPECT_NEAR(back.header.getDouble("GAIN").value_or(0.0), p.gainEPerAdu, 1e-12);
  EXPECT_TRUE(back.header.has("DATE-OBS"));
  // The cube in memory carries the same WCS as the one read back (the GUI's demo uses it unwritten: it had
  // no WCS, so no sky positions, until its cache was read on the next start).
  ASSERT_TRUE(r.cube.wcs);
  for (const auto& [x, y] : {std::pair{0.0, 0.0}, std::pair{100.0, 37.0}})
    for (const auto& c : {r.cube.wcs->pixelToSky(x, y)}) {
      const auto b = back.wcs->pixelToSky(x, y);
      EXPECT_NEAR(c.raDeg, b.raDeg, 1e-12);
      EXPECT_NEAR(c.decDeg, b.decDeg, 1e-12);
    }
}

// The chained pre-processing on the simulator's "small" preset (conventional CCD, stars, a saturated star,
// cosmic rays, hot pixels, one moving object), scored against the truth: sigma_n within 3%, background bias
// < 0.05 sigma, >= 95% of the cosmic-ray hits removed, no pixel of the moving object removed, PSF FWHM within
// 5% (fitted on the sky-rate stack).
#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include "st/pipeline/preprocess.hpp"
#include "st/sim/simulator.hpp"
#include "track_pixels.hpp"

namespace st::pipeline {
namespace {

TEST(PipelineSim, SmallPresetAgainstTruth) {
  NullProgress p;
  CancelToken c;
  sim::SimResult sim = sim::simulate(sim::preset("small"), 7, p, c);
  const sim::Truth truth = sim.truth;
  PreprocessParams params;
  params.masters = sim::exactMasters(sim);
  const Prepared out = preprocess(std::move(sim.cube), params, p, c);

  double sigmaTruth = 0.0, skyTruth = 0.0;
  for (double v : truth.noiseSigmaAdu)
    sigmaTruth += v / truth.noiseSigmaAdu.size();
  for (double v : truth.skyAdu)
    skyTruth += v / truth.skyAdu.size();
  EXPECT_NEAR(out.sigmaN, sigmaTruth, 0.03 * sigmaTruth);
  double bias = 0.0;
  for (float v : out.background.pixels)
    bias += (v - skyTruth) / out.background.size();
  EXPECT_LT(std::abs(bias), 0.05 * sigmaTruth);
  // Integer-shift resolution: an error below 0.5 px over half the span shifts no frame differently.
  const double span = out.frames.timeSpanS();
  EXPECT_NEAR(out.skyRate.vx, truth.skyVxPxPerS, 1.0 / span);
  EXPECT_NEAR(out.skyRate.vy, truth.skyVyPxPerS, 1.0 / span);
  ASSERT_TRUE(out.psfFitted) << out.notes.back();
  EXPECT_NEAR(out.psf.fwhm(), truth.psfFwhmPx, 0.05 * truth.psfFwhmPx)
      << "PSF star at " << out.psfStarAt->first << "," << out.psfStarAt->second << " of " << out.stars.size()
      << " catalog stars; beta " << out.psf.beta;

  const int w = out.frames.width();
  const std::size_t np = out.frames.framePixels();
  const std::set<std::uint64_t> flagged(out.cosmicRayPixels.begin(), out.cosmicRayPixels.end());
  std::set<std::uint64_t> hitPixels;
  std::size_t hits = 0, removed = 0;
  for (const auto& cr : truth.cosmicRays) {
    bool any = false;
    for (const auto& [x, y] : cr.pixels) {
      const std::uint64_t q = cr.frame * np + static_cast<std::size_t>(y) * w + x;
      hitPixels.insert(q);
      any |= flagged.count(q) != 0 || out.frames.pixels()[q] == 0.0f;  // zeroed as a hit or under a star
    }
    ++hits;
    removed += any;
  }
  ASSERT_GT(hits, 10u);
  EXPECT_GE(removed, (hits * 95 + 99) / 100) << removed << " of " << hits << " hits removed";
  std::size_t objectPixels = 0, objectZeroed = 0;
  for (const auto& o : truth.objects) {
    const auto [pixels, zeroed] = test::zeroedAlongTrack(out.frames, o, hitPixels);
    objectPixels += pixels;
    objectZeroed += zeroed;
  }
  ASSERT_GT(objectPixels, 100u);
  EXPECT_EQ(objectZeroed, 0u) << "pixels of the moving object removed";
  for (float v : out.filtered.frames.pixels())
    ASSERT_TRUE(std::isfinite(v));
  EXPECT_GT(out.filtered.sigmaF, 0.0);
}

}  // namespace
}  // namespace st::pipeline

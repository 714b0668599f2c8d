// The paper's 2009 BL2 night (simulator preset "known-pair": a V = 18.5 asteroid moving 0.6 deg/day,
// 0.077 px/s, expected SNR ~4100 over 960 frames at 2 Hz), reduced with sim::resize to 128 x 128 px and 480
// frames (240 s, the object 18 px over the span, expected SNR ~2900) so that it runs in seconds. The object
// is bright and slow: every pixel along its track peaks at the same value in the stack's per-pixel maximum
// (a plateau the flat-top saturation test took for a saturated star, so it was masked and not found), and
// it pulled the block-pair sky rate to ~(0.04, 0.02) px/s. Oracles (the truth): the sky rate (0, no drift)
// within 0.002 px/s (0.5 px over the span); exactly one mover, within 1 px of the truth and 10% of its
// velocity; not catalogued as a (saturated) star; the search's best candidate within 2 px and 1.5 grid
// steps (1.5 px over the span each) of the truth with >= 75% of its expected SNR.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "st/pipeline/preprocess.hpp"
#include "st/sim/simulator.hpp"
#include "truth_search.hpp"

namespace st::pipeline {
namespace {

TEST(PipelineKnownPair, BrightSlowAsteroidFoundNotMaskedAsASaturatedStar) {
  sim::SimParams params = sim::preset("known-pair");
  sim::resize(params, 128, 128, 480);
  NullProgress p;
  CancelToken c;
  sim::SimResult sim = sim::simulate(params, 1, p, c);
  const sim::TruthObject obj = sim.truth.objects.at(0);
  PreprocessParams pp;
  pp.masters = sim::exactMasters(sim);
  const Prepared out = preprocess(std::move(sim.cube), pp, p, c);
  EXPECT_NEAR(out.skyRate.vx, 0.0, 0.002);
  EXPECT_NEAR(out.skyRate.vy, 0.0, 0.002);
  for (const auto& s : out.stars)
    EXPECT_GT(std::hypot(s.x - obj.xRefPx, s.y - obj.yRefPx), 3.0)
        << "the asteroid catalogued as a star (saturated: " << s.saturated << ")";
  ASSERT_EQ(out.movers.size(), 1u);
  const detect::MovingSource& mv = out.movers.front();
  const double speed = std::hypot(obj.vxPxPerS, obj.vyPxPerS);
  EXPECT_NEAR(mv.x, obj.xRefPx, 1.0);
  EXPECT_NEAR(mv.y, obj.yRefPx, 1.0);
  EXPECT_NEAR(mv.v.vx, obj.vxPxPerS, 0.1 * speed);
  EXPECT_NEAR(mv.v.vy, obj.vyPxPerS, 0.1 * speed);

  // The demo's step (1.5 px over the span), 9 x 9 velocities around the sky rate plus the asteroid's rate.
  const double step = 1.5 / out.filtered.frames.timeSpanS();
  const search::VelocityGrid grid{{out.skyRate.vx + 0.077, out.skyRate.vy + 0.028}, step, 9, 9};
  const auto found = test::expectBestIsObject(out.filtered, grid, obj, 2.0);
  ASSERT_TRUE(found);
  const search::Candidate& best = *found;
  std::printf(
      "known-pair 128x128x480: sky rate (%.5f, %.5f); mover (%.2f, %.2f) v (%.4f, %.4f); truth (%.2f, "
      "%.2f) v (%.4f, %.4f) expected SNR %.0f; best (%d, %d) v (%.4f, %.4f) SNR %.0f\n",
      out.skyRate.vx, out.skyRate.vy, mv.x, mv.y, mv.v.vx, mv.v.vy, obj.xRefPx, obj.yRefPx, obj.vxPxPerS,
      obj.vyPxPerS, obj.expectedSnr, best.x, best.y, best.v.vx, best.v.vy, best.snr);
}

}  // namespace
}  // namespace st::pipeline

// The sky rate over many seeds of the paper-neo preset (label "slow"): 500 frames of 512 x 512 at 16.7 Hz,
// the stars drifting 16.4 px/s (5"/s), so that the star field moves 490 px over the 30 s span and the first
// and last frames share almost no stars. Before the chained refinement, stacks of the first and last thirds
// (which share no stars) were compared: seed 21 gave (-3.15, -1.42) px/s for a truth of (16.39, 0). Oracle:
// the simulator's drift within 0.01 px/s (0.3 px over the span) on every seed, measured on the calibrated
// cube (exact masters) with the global background removed and the hot pixels masked, as the pre-processing
// does before it; seeds 1 and 21 (the reported failure), and seeds 21..40 through the pipeline in
// test_pipeline_seeds_slow.cpp (until 2026-12-03 seeds 1..21 here). Measured 2026-11-25 on the 2-core dev
// machine: largest error 0.0039 px/s over seeds 1..20, 0.0017 on seed 21; ~2 s per measurement, ~30 s per
// seed with the simulation (7.7 min for the 21 seeds). The 1500-frame cube (90 s, the field crossing the
// frame three times) of the report, `synthtrack-cli simulate --preset paper-neo --frames 1500 --seed 5`,
// measured the same way: error (+0.0004, +0.0007) px/s; through `synthtrack-cli preprocess` on the raw frames
// (the report's run): block pairs (15.97, 0.49), chained (16.3934, 0.0006) px/s for a truth of (16.3934, 0).
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>

#include "st/calib/calibration.hpp"
#include "st/detect/hot_pixels.hpp"
#include "st/detect/sky_rate.hpp"
#include "st/sim/simulator.hpp"
#include "st/stats/background.hpp"

namespace st::detect {
namespace {

class SkyRatePaperNeo : public ::testing::TestWithParam<int> {};

TEST_P(SkyRatePaperNeo, WithinOneHundredthOfAPixelPerSecond) {
  const int seed = GetParam();
  const sim::SimParams params = sim::preset("paper-neo");
  NullProgress p;
  CancelToken c;
  sim::SimResult sim = sim::simulate(params, static_cast<std::uint64_t>(seed), p, c);
  const calib::MasterCalibration m = sim::exactMasters(sim);
  FrameCube& cube = sim.cube;
  calib::applyCalibration(cube, m, {}, p, c);
  const stats::ClipStats global = stats::globalBackground(cube);
  maskPixelsInAllFrames(cube, findHotPixels(cube, global.mean, global.sigma, {}, c));
  const auto t0 = std::chrono::steady_clock::now();
  const SkyRate r = measureSkyRate(cube, global.mean, global.sigma, {}, c);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("seed %d: measured (%.4f, %.4f) px/s in %.1f s, truth (%.4f, %.4f), error (%+.4f, %+.4f); %s\n",
              seed, r.rate.vx, r.rate.vy, seconds, sim.truth.skyVxPxPerS, sim.truth.skyVyPxPerS,
              r.rate.vx - sim.truth.skyVxPxPerS, r.rate.vy - sim.truth.skyVyPxPerS, r.note.c_str());
  ASSERT_TRUE(r.reliable) << r.note;
  EXPECT_TRUE(r.chained) << r.note;
  EXPECT_NEAR(r.rate.vx, sim.truth.skyVxPxPerS, 0.01) << r.note;
  EXPECT_NEAR(r.rate.vy, sim.truth.skyVyPxPerS, 0.01) << r.note;
  // The simulated field moves exactly linearly: the blocks' departures from the line are measurement noise.
  EXPECT_LT(r.residualRmsPx, 0.3) << r.note;
}

// Two seeds here: the first, and 21 (the reported failure). The same oracle over 20 seeds (21..40) is checked
// on the pipeline's own measurement in test_pipeline_seeds_slow.cpp, which simulates those seeds anyway: the
// 19 further seeds here cost CI ~9 minutes of simulation (2026-12-03).
INSTANTIATE_TEST_SUITE_P(Seeds, SkyRatePaperNeo, ::testing::Values(1, 21));

}  // namespace
}  // namespace st::detect

// Velocity grid construction, trial counts and the cost estimate: pure arithmetic, checked exactly.
#include <gtest/gtest.h>

#include <string>

#include "st/common/error.hpp"
#include "st/search/velocity_grid.hpp"

namespace st::search {
namespace {

TEST(SearchGrid, PaperRuleOnePixelOverTheSpan) {
  // 30 s span, +-0.5 px/s: step 1/30 px/s, ceil(0.5 * 30) = 15 steps each side -> 31 x 31.
  GridSpec spec;
  spec.halfRange = 0.5;
  const VelocityGrid g = makeVelocityGrid(spec, 30.0, 3.0, Velocity{0.0, 0.0});
  EXPECT_DOUBLE_EQ(g.stepPxS, 1.0 / 30.0);
  EXPECT_EQ(g.nvx, 31);
  EXPECT_EQ(g.nvy, 31);
  EXPECT_EQ(g.count(), 961u);
  EXPECT_NEAR(g.at(0, 0).vx, -0.5, 1e-12);
  EXPECT_NEAR(g.at(30, 30).vy, 0.5, 1e-12);
  EXPECT_DOUBLE_EQ(g.at(15, 15).vx, 0.0);
}

TEST(SearchGrid, PaperGridInDegPerDay) {
  // Paper §4.4: +-12 deg/day, 1 px per 90 s integration, plate scale 0.305"/px (binned CHIMERA):
  // 12 deg/day = 12 * 3600 / 86400 / 0.305 = 1.639344 px/s; step 1/90 px/s -> 147.54 -> 148 steps each side.
  GridSpec spec;
  spec.halfRange = 12.0;
  spec.unit = VelocityUnit::DegPerDay;
  spec.plateScaleArcsecPerPx = 0.305;
  const VelocityGrid g = makeVelocityGrid(spec, 90.0, 3.0, Velocity{});
  EXPECT_EQ(g.nvx, 2 * 148 + 1);
  const TrialCounts t = trialCounts(512, 512, g);
  EXPECT_EQ(t.nx, 512);
  EXPECT_EQ(t.nvy, 297);
  EXPECT_DOUBLE_EQ(t.total(), 512.0 * 512.0 * 297.0 * 297.0);
}

TEST(SearchGrid, UnitsAndCentre) {
  EXPECT_DOUBLE_EQ(toPxPerS(2.0, VelocityUnit::PxPerS, std::nullopt), 2.0);
  EXPECT_DOUBLE_EQ(toPxPerS(60.0, VelocityUnit::ArcsecPerMin, 0.5), 2.0);  // 60"/min = 1"/s = 2 px/s
  EXPECT_NEAR(toPxPerS(24.0, VelocityUnit::DegPerDay, 1.0), 1.0, 1e-15);   // 24 deg/day = 1"/s
  EXPECT_THROW(toPxPerS(1.0, VelocityUnit::DegPerDay, std::nullopt), InputError);
  EXPECT_THROW(toPxPerS(1.0, VelocityUnit::ArcsecPerMin, 0.0), InputError);
  GridSpec spec;
  spec.halfRange = 1.0;
  spec.stepRule = StepRule::PxPerS;
  spec.stepPxS = 0.5;
  // Default centre: the sky rate.
  VelocityGrid g = makeVelocityGrid(spec, 10.0, 3.0, Velocity{3.0, -1.0});
  EXPECT_EQ(g.nvx, 5);
  EXPECT_DOUBLE_EQ(g.at(2, 2).vx, 3.0);
  EXPECT_DOUBLE_EQ(g.at(0, 4).vy, 0.0);
  spec.centre = Velocity{0.25, 0.5};
  g = makeVelocityGrid(spec, 10.0, 3.0, Velocity{3.0, -1.0});
  EXPECT_DOUBLE_EQ(g.at(2, 2).vx, 0.25);
  EXPECT_DOUBLE_EQ(g.at(2, 2).vy, 0.5);
}

TEST(SearchGrid, StepRules) {
  GridSpec spec;
  spec.halfRange = 1.0;
  spec.stepRule = StepRule::FwhmOverSpan;
  EXPECT_DOUBLE_EQ(gridStepPxS(spec, 20.0, 3.0), 0.15);
  spec.stepRule = StepRule::PixelsOverSpan;
  spec.stepPx = 0.5;
  EXPECT_DOUBLE_EQ(gridStepPxS(spec, 20.0, 3.0), 0.025);
  // An exact multiple stays exact: range 1, step 0.25 -> 4 steps each side -> 9.
  spec.stepRule = StepRule::PxPerS;
  spec.stepPxS = 0.25;
  EXPECT_EQ(makeVelocityGrid(spec, 20.0, 3.0, Velocity{}).nvx, 9);
  // Range 0: one velocity (a stack at the centre).
  spec.halfRange = 0.0;
  EXPECT_EQ(makeVelocityGrid(spec, 20.0, 3.0, Velocity{}).count(), 1u);
}

TEST(SearchGrid, BadInputSaysWhatIsWrong) {
  GridSpec spec;
  spec.halfRange = 1.0;
  EXPECT_THROW(makeVelocityGrid(spec, 0.0, 3.0, Velocity{}), InputError);  // one frame / zero span
  spec.stepPx = 0.0;
  EXPECT_THROW(makeVelocityGrid(spec, 10.0, 3.0, Velocity{}), InputError);
  spec.stepPx = 1.0;
  spec.halfRange = -1.0;
  EXPECT_THROW(makeVelocityGrid(spec, 10.0, 3.0, Velocity{}), InputError);
  spec.halfRange = 1.0;
  spec.stepRule = StepRule::FwhmOverSpan;
  EXPECT_THROW(makeVelocityGrid(spec, 10.0, 0.0, Velocity{}), InputError);
  // Too many trials: 1 px/s over 1000 s -> 2001^2 = 4e6 > 1e6; says what would fit.
  spec.stepRule = StepRule::PixelsOverSpan;
  spec.maxVelocities = 1'000'000;
  try {
    makeVelocityGrid(spec, 1000.0, 3.0, Velocity{});
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("2001 x 2001"), std::string::npos) << msg;
    EXPECT_NE(msg.find("1000 per axis"), std::string::npos) << msg;
  }
}

TEST(SearchGrid, EstimateIsExactArithmetic) {
  const VelocityGrid g{{0, 0}, 0.01, 100, 100};
  const SearchEstimate e = estimateSearch(512, 512, 1500, g, 2, 2e10);
  EXPECT_DOUBLE_EQ(e.additions, 1500.0 * 512 * 512 * 100 * 100);
  EXPECT_EQ(e.cubeBytes, 1500u * 512u * 512u * 4u);
  EXPECT_DOUBLE_EQ(e.seconds, e.additions / 2e10);
  EXPECT_GT(e.workingBytes, 10000u * 12u);        // at least the velocity map
  EXPECT_LT(e.workingBytes, 300u * 1024 * 1024);  // the budget: cube + 300 MB
  const SearchEstimate d = estimateSearch(512, 512, 1500, g, 2);
  EXPECT_DOUBLE_EQ(d.throughputPerS, 2 * kCpuAdditionsPerSecondPerThread);
}

}  // namespace
}  // namespace st::search

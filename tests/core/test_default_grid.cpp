// The data-derived default velocity grid (st/search/default_grid.hpp): each of its three bounds, checked
// with exact arithmetic, and the Lowell 42-inch sequence of issue 15 item 4 (72 min, 0.981"/px) that the
// paper's +-12 deg/day made a ~20 M velocity search.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "st/common/error.hpp"
#include "st/common/units.hpp"
#include "st/search/default_grid.hpp"

namespace st::search {
namespace {

MethodCostModel flatModel(double additionsPerS) {
  MethodCostModel m;
  m.exactAdditionsPerS = additionsPerS;  // no fixed cost, no width scaling: the arithmetic is exact
  return m;
}

TEST(DefaultGrid, PaperRangeWhenTheBackendIsFastAndTheFrameLarge) {
  // Paper §4.4 problem: 90 s, 0.305"/px: 12 deg/day = 1.639 px/s = 147.5 steps of 1/90 -> 148.
  DefaultGridInput in;
  in.width = in.height = 512;
  in.frames = 1500;
  in.timeSpanS = 90.0;
  in.plateScaleArcsecPerPx = 0.305;
  in.model = flatModel(1e16);
  in.centre = Velocity{16.0, 0.5};
  const DefaultGrid g = defaultVelocityGrid(in);
  EXPECT_EQ(g.limit, DefaultGridLimit::Paper);
  EXPECT_EQ(g.halfSteps, 148);
  EXPECT_EQ(g.grid.nvx, 297);
  EXPECT_EQ(g.grid.nvy, 297);
  EXPECT_DOUBLE_EQ(g.grid.stepPxS, 1.0 / 90.0);
  EXPECT_DOUBLE_EQ(g.grid.centre.vx, 16.0);
  EXPECT_NEAR(g.paperLimitPxS, degPerDayToPxPerSec(12.0, 0.305), 1e-12);
  // The frame: 512 px over half the 90 s span.
  EXPECT_NEAR(g.frameLimitPxS, 512.0 / 45.0, 1e-12);
  EXPECT_NEAR(g.exactSeconds, 512.0 * 512 * 1500 * 297 * 297 / 1e16, 1e-12);
}

TEST(DefaultGrid, FrameLimitsAFastSequenceOfSmallFrames) {
  // 64 x 48 px over 10 s at 0.01"/px: 12 deg/day is 50 px/s, but the frame allows 64 / (0.5 x 10) = 12.8
  // px/s = 128 steps of 0.1 px/s.
  DefaultGridInput in;
  in.width = 64;
  in.height = 48;
  in.frames = 20;
  in.timeSpanS = 10.0;
  in.plateScaleArcsecPerPx = 0.01;
  in.model = flatModel(1e16);
  const DefaultGrid g = defaultVelocityGrid(in);
  EXPECT_EQ(g.limit, DefaultGridLimit::Frame);
  EXPECT_NEAR(g.frameLimitPxS, 12.8, 1e-12);
  EXPECT_EQ(g.halfSteps, 128);
  EXPECT_NEAR(g.halfRangePxS, 12.8, 1e-9);
}

TEST(DefaultGrid, BudgetCapsTheVelocityCount) {
  // 100 x 100 px x 10 frames = 1e5 additions per velocity at 1e7/s: 0.01 s each; 60 s -> 6000 velocities ->
  // (2k+1)^2 <= 6000 -> k = 38 (77^2 = 5929; 79^2 = 6241 is over).
  DefaultGridInput in;
  in.width = in.height = 100;
  in.frames = 10;
  in.timeSpanS = 1000.0;
  in.plateScaleArcsecPerPx = 1.0;
  in.model = flatModel(1e7);
  const DefaultGrid g = defaultVelocityGrid(in);
  EXPECT_EQ(g.limit, DefaultGridLimit::Budget);
  EXPECT_EQ(g.halfSteps, 38);
  EXPECT_EQ(g.grid.nvx, 77);
  EXPECT_NEAR(g.exactSeconds, 5929 * 0.01, 1e-9);
  EXPECT_LE(g.exactSeconds, in.budgetS);
  EXPECT_NEAR(g.budgetLimitPxS, 38 / 1000.0, 1e-15);
  // A fixed start-up cost comes out of the budget: 10 s -> 5000 velocities -> k = 34 (69^2 = 4761).
  in.model.exactFixedS = 10.0;
  EXPECT_EQ(defaultVelocityGrid(in).halfSteps, 34);
  // Never less than 3 x 3.
  in.model = flatModel(1.0);
  EXPECT_EQ(defaultVelocityGrid(in).halfSteps, 1);
}

TEST(DefaultGrid, WithoutPlateScaleTwelveStepsAsTheCli) {
  DefaultGridInput in;
  in.width = in.height = 64;
  in.frames = 20;
  in.timeSpanS = 1.9;
  in.model = flatModel(1e12);
  const DefaultGrid g = defaultVelocityGrid(in);
  EXPECT_EQ(g.limit, DefaultGridLimit::Paper);
  EXPECT_EQ(g.halfSteps, 12);
  EXPECT_EQ(g.grid.nvx, 25);
  const std::string text = describeDefaultGrid(g, std::nullopt);
  EXPECT_NE(text.find("px/s"), std::string::npos) << text;
  EXPECT_NE(text.find("25 × 25"), std::string::npos) << text;
}

TEST(DefaultGrid, LowellSequenceSearchesInAboutAMinuteOnTwoCores) {
  // Issue 15 item 4: 15 x 300 s frames at ~309 s cadence (span 72 min), 1365 x 1370 px after the trim,
  // 0.981"/px: the paper's +-12 deg/day is 2205 steps each side (19.5 M velocities, hours on a CPU).
  DefaultGridInput in;
  in.width = 1365;
  in.height = 1370;
  in.frames = 15;
  in.timeSpanS = 4326.0;
  in.plateScaleArcsecPerPx = 0.981;
  in.model = cpuCostModel(2);
  const DefaultGrid g = defaultVelocityGrid(in);
  EXPECT_EQ(g.limit, DefaultGridLimit::Budget);
  EXPECT_LE(g.exactSeconds, in.budgetS);
  EXPECT_GT(g.exactSeconds, 0.8 * in.budgetS);
  // Wide enough for a main-belt asteroid (5945: 8"/h = 0.05 deg/day) and far below the paper's range.
  const double halfDegDay = pxPerSecToDegPerDay(g.halfRangePxS, 0.981);
  EXPECT_GT(halfDegDay, 0.2);
  EXPECT_LT(halfDegDay, 2.0);
  EXPECT_LT(g.grid.count(), 200'000u);
  const std::string text = describeDefaultGrid(g, 0.981);
  EXPECT_NE(text.find("deg/day"), std::string::npos) << text;
  EXPECT_NE(text.find("time budget"), std::string::npos) << text;
}

TEST(DefaultGrid, BadInputNamesTheValue) {
  DefaultGridInput in;
  in.width = in.height = 10;
  in.frames = 5;
  in.model = flatModel(1e9);
  try {
    (void)defaultVelocityGrid(in);
    FAIL() << "no throw for a zero span";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("time span"), std::string::npos) << e.what();
  }
  in.timeSpanS = 10.0;
  in.model = MethodCostModel{};
  EXPECT_THROW((void)defaultVelocityGrid(in), InputError);
}

}  // namespace
}  // namespace st::search

// Segment checks (paper §5.1): real moving sources pass, transients and jumping tracks are flagged.
#include <gtest/gtest.h>

#include <cmath>

#include "st/common/error.hpp"
#include "st/fit/montecarlo.hpp"
#include "st/vet/segments.hpp"

namespace st::vet {
namespace {

const psf::Moffat kPsf{3.3, 4.0};

TEST(Segments, EqualTimeSplit) {
  std::vector<double> t;
  for (int n = 0; n < 10; ++n)
    t.push_back(n);
  const auto s = splitEqualTime(t, 4);
  ASSERT_EQ(s.size(), 4u);
  EXPECT_EQ(s[0], (std::vector<std::size_t>{0, 1, 2}));
  EXPECT_EQ(s[1], (std::vector<std::size_t>{3, 4}));
  EXPECT_EQ(s[2], (std::vector<std::size_t>{5, 6}));
  EXPECT_EQ(s[3], (std::vector<std::size_t>{7, 8, 9}));
  // Equal time, not equal counts: a gap leaves a segment empty.
  const auto g = splitEqualTime({0.0, 0.1, 0.2, 9.8, 9.9, 10.0}, 4);
  EXPECT_EQ(g[0].size(), 3u);
  EXPECT_TRUE(g[1].empty());
  EXPECT_TRUE(g[2].empty());
  EXPECT_EQ(g[3].size(), 3u);
  EXPECT_THROW((void)splitEqualTime(t, 0), InputError);
  EXPECT_THROW((void)splitEqualTime(t, 11), InputError);
}

TEST(Segments, ChiSquareSurvivalKnownValues) {
  for (double x : {0.5, 2.0, 7.0, 20.0})
    EXPECT_NEAR(chiSquareSurvival(x, 2), std::exp(-x / 2), 1e-12);
  EXPECT_NEAR(chiSquareSurvival(3.841459, 1), 0.05, 1e-6);
  EXPECT_NEAR(chiSquareSurvival(9.487729, 4), 0.05, 1e-6);
  EXPECT_NEAR(chiSquareSurvival(23.209251, 10), 0.01, 1e-6);
  EXPECT_NEAR(chiSquareSurvival(0.710723, 4), 0.95, 1e-6);
  EXPECT_EQ(chiSquareSurvival(5.0, 0), 1.0);
}

TEST(Segments, StackStampIsIpsaAlongTheTrack) {
  FrameCube cube = fit::makeEmptyCube(30, 5, 1.0);  // t = -2 .. 2 s
  const std::vector<double> t = cube.timeOffsetsS();
  for (std::size_t n = 0; n < 5; ++n) {
    const int x = 15 + static_cast<int>(std::lround(2.0 * t[n]));
    const int y = 10 - static_cast<int>(std::lround(1.0 * t[n]));
    cube.frame(n)[y * 30 + x] = 1.0f;
  }
  const Image s = stackStamp(cube, {0, 1, 2, 3, 4}, 15.2, 9.9, {2.0, -1.0}, 0.0, 3);
  EXPECT_FLOAT_EQ(s.at(3, 3), 5.0f);
  EXPECT_FLOAT_EQ(s.at(4, 3), 0.0f);
}

struct Scene {
  FrameCube cube;
  fit::FitResult fit;
  fit::FitOptions options;
};

// Fits the whole cube from a start near (x, y, v) and returns everything the segment check needs.
Scene fitScene(FrameCube cube, double x, double y, Velocity v, double sigmaN) {
  Scene s{std::move(cube), {}, {}};
  s.options.psf = kPsf;
  s.options.sigmaN = sigmaN;
  s.fit = fit::fitComoving(s.cube, {v, std::round(x), std::round(y), std::nan(""), 0.0}, s.options);
  return s;
}

TEST(Segments, ARealMovingSourcePasses) {
  for (std::uint64_t seed : {1u, 2u, 3u}) {
    FrameCube cube = fit::makeEmptyCube(48, 60, 0.06);
    fit::renderMovingSource(cube, kPsf, {24.3, 23.8, {3.0, -2.0}, 120.0});
    fit::addNoise(cube, 3.0, true, seed);
    Scene s = fitScene(std::move(cube), 24.3, 23.8, {3.0, -2.0}, 3.0);
    ASSERT_TRUE(s.fit.ok()) << s.fit.message;
    CancelToken cancel;
    const SegmentReport r = checkSegments(s.cube, s.fit, s.options, {}, cancel);
    ASSERT_EQ(r.segments.size(), 4u);
    EXPECT_FALSE(r.flagged()) << (r.reasons.empty() ? "" : r.reasons[0]);
    EXPECT_EQ(r.positionDof, 4);
    for (const auto& m : r.segments) {
      EXPECT_EQ(m.frames.size(), 15u);
      EXPECT_NEAR(m.expectedSnr, s.fit.snr / 2.0, 1e-9);
      EXPECT_NEAR(m.forcedSnr, m.expectedSnr, 4.0);
      EXPECT_EQ(m.fitStatus, fit::FitStatus::Converged);
      EXPECT_NEAR(m.x, m.predictedX, 5 * m.sigmaX);
      EXPECT_EQ(m.stack.width, 2 * fit::defaultStampHalfSize(kPsf) + 1);
    }
  }
}

TEST(Segments, ATransientInOneSegmentIsFlagged) {
  FrameCube signal = fit::makeEmptyCube(48, 60, 0.06);
  fit::renderMovingSource(signal, kPsf, {24.3, 23.8, {3.0, -2.0}, 400.0});
  FrameCube cube = fit::makeEmptyCube(48, 60, 0.06);
  for (std::size_t n = 0; n < 15; ++n) {  // present in the first quarter only
    std::copy_n(signal.frame(n), signal.framePixels(), cube.frame(n));
  }
  fit::addNoise(cube, 3.0, true, 9);
  Scene s = fitScene(std::move(cube), 24.3, 23.8, {3.0, -2.0}, 3.0);
  // The whole fit of a transient may wander along a noise-driven valley (max-iterations); the segment check
  // works from whatever track it ended on.
  ASSERT_TRUE(s.fit.params.toVector().allFinite());
  CancelToken cancel;
  const SegmentReport r = checkSegments(s.cube, s.fit, s.options, {}, cancel);
  EXPECT_TRUE(r.flagged());
  EXPECT_TRUE(r.missingSignal);
  EXPECT_FALSE(r.segments[0].missing);
  EXPECT_TRUE(r.segments[2].missing);
  EXPECT_TRUE(r.segments[3].missing);
  EXPECT_TRUE(r.fluxInconsistent);
  EXPECT_FALSE(r.reasons.empty());
}

TEST(Segments, ATrackThatJumpsIsFlagged) {
  // Two sources on parallel tracks 2.5 px apart, one before mid-time and one after: a cosmic-ray-chain-like
  // stitched detection. Each half alone is a fine point source.
  FrameCube a = fit::makeEmptyCube(48, 60, 0.06), b = fit::makeEmptyCube(48, 60, 0.06);
  fit::renderMovingSource(a, kPsf, {24.3, 22.6, {3.0, 0.0}, 600.0});
  fit::renderMovingSource(b, kPsf, {24.3, 25.1, {3.0, 0.0}, 600.0});
  FrameCube cube = fit::makeEmptyCube(48, 60, 0.06);
  for (std::size_t n = 0; n < 60; ++n) {
    const FrameCube& src = n < 30 ? a : b;
    std::copy_n(src.frame(n), src.framePixels(), cube.frame(n));
  }
  fit::addNoise(cube, 3.0, true, 4);
  Scene s = fitScene(std::move(cube), 24.3, 23.8, {3.0, 0.0}, 3.0);
  ASSERT_TRUE(s.fit.params.toVector().allFinite());
  if (!s.fit.ok()) GTEST_SKIP() << "whole fit did not converge: " << s.fit.message;  // also a rejection
  CancelToken cancel;
  const SegmentReport r = checkSegments(s.cube, s.fit, s.options, {}, cancel);
  EXPECT_TRUE(r.offTrack) << "chi2 " << r.positionChi2 << " dof " << r.positionDof;
  EXPECT_TRUE(r.flagged());
}

}  // namespace
}  // namespace st::vet

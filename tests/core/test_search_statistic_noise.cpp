// The search statistic's noise measured on the cube (statistic_noise.hpp). Oracles: on frames of independent
// Gaussian noise of standard deviation sigma_F the statistic S / (sigma_F sqrt(N_in)) has unit variance (the
// paper's Prob_false assumption); a pattern that stays in place, added to every frame, adds coherently along
// a track that stays on one pixel: var = 1 + N a^2 / sigma_F^2 for N frames and a pattern of standard
// deviation a. Tolerances: 4 of the measurement's own standard errors.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "st/search/cpu_backend.hpp"
#include "st/search/method_choice.hpp"
#include "st/search/statistic_noise.hpp"

namespace st::search {
namespace {

constexpr int kSide = 128;
constexpr int kFrames = 16;
constexpr double kSigma = 2.0;

// kFrames frames 1 s apart of N(0, kSigma^2), plus `pattern` (the same in every frame) of standard
// deviation patternSigma.
FilteredCube noiseCube(double patternSigma, unsigned seed) {
  FilteredCube c;
  c.frames = FrameCube(kSide, kSide, kFrames);
  std::mt19937 rng(seed);
  std::normal_distribution<float> g(0.0f, 1.0f);
  std::vector<float> pattern(static_cast<std::size_t>(kSide) * kSide);
  for (float& p : pattern)
    p = static_cast<float>(patternSigma) * g(rng);
  for (std::size_t n = 0; n < kFrames; ++n) {
    c.frames.info()[n].mjdMid = 60000.0 + static_cast<double>(n) / 86400.0;
    float* f = c.frames.frame(n);
    for (std::size_t i = 0; i < pattern.size(); ++i)
      f[i] = static_cast<float>(kSigma) * g(rng) + pattern[i];
  }
  c.sigmaF = kSigma;
  return c;
}

VelocityGrid grid(int n, double step) {
  return VelocityGrid{{0.0, 0.0}, step, n, n};
}

TEST(StatisticNoise, IndependentGaussianFramesHaveTheUnit) {
  CancelToken cancel;
  for (unsigned seed : {1u, 2u, 3u}) {
    const FilteredCube c = noiseCube(0.0, seed);
    const StatisticNoise n = measureStatisticNoise(c, grid(9, 0.5), kFrames / 2, cancel);
    ASSERT_TRUE(n.measured());
    // Tracks of up to 2 px/s over 15 s leave the frame near its edges; most keep N_in >= 8.
    EXPECT_GT(n.cells, statisticNoiseCells(kFrames) * 3 / 4);
    EXPECT_NEAR(n.scale, 1.0, 4.0 * n.standardError) << "seed " << seed;
    EXPECT_NEAR(n.mean, 0.0, 4.0 * n.scale / std::sqrt(n.cells)) << "seed " << seed;
    EXPECT_NEAR(n.standardError, n.scale / std::sqrt(2.0 * n.cells), 0.02 * n.standardError);
  }
}

TEST(StatisticNoise, AStaticPatternAddsCoherentlyOnASlowTrack) {
  CancelToken cancel;
  // One velocity, 0: every frame's sample is the same pixel. a = sigma_F / 4: var = 1 + 16 / 16 = 2.
  const FilteredCube c = noiseCube(kSigma / 4.0, 7);
  const StatisticNoise n = measureStatisticNoise(c, grid(1, 0.5), kFrames, cancel);
  ASSERT_TRUE(n.measured());
  EXPECT_NEAR(n.scale, std::sqrt(2.0), 4.0 * n.standardError);
  // Fast tracks cross a new pixel every frame: the pattern is one more independent term, var = 1 + a^2 /
  // sigma_F^2 = 1.0625 (velocities of 3 and more px/s, none of them 0).
  const StatisticNoise fast =
      measureStatisticNoise(c, VelocityGrid{{6.0, 6.0}, 1.0, 5, 5}, kFrames / 4, cancel);
  ASSERT_TRUE(fast.measured());
  EXPECT_NEAR(fast.scale, std::sqrt(1.0625), 4.0 * fast.standardError);
}

TEST(StatisticNoise, SourcesOnAFewTracksAreClippedNotCounted) {
  CancelToken cancel;
  FilteredCube c = noiseCube(0.0, 11);
  // 40 bright static points: every track that starts on one at velocity 0 sums 16 x 20 sigma.
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> u(0, kSide - 1);
  for (int k = 0; k < 40; ++k) {
    const std::size_t i = static_cast<std::size_t>(u(rng)) * kSide + u(rng);
    for (std::size_t n = 0; n < kFrames; ++n)
      c.frames.frame(n)[i] += static_cast<float>(20.0 * kSigma);
  }
  const StatisticNoise n = measureStatisticNoise(c, grid(1, 0.5), kFrames, cancel);
  ASSERT_TRUE(n.measured());
  EXPECT_NEAR(n.scale, 1.0, 4.0 * n.standardError);
}

TEST(StatisticNoise, NotMeasuredWithoutEnoughCellsOrNoise) {
  CancelToken cancel;
  FilteredCube c = noiseCube(0.0, 3);
  // 100 px/s leaves the 128 px frame within 2 frames: no cell keeps all 16.
  EXPECT_FALSE(measureStatisticNoise(c, VelocityGrid{{100.0, 100.0}, 1.0, 3, 3}, kFrames, cancel).measured());
  c.sigmaF = 0.0;
  EXPECT_FALSE(measureStatisticNoise(c, grid(3, 0.5), 1, cancel).measured());
}

TEST(StatisticNoise, EverySearchReportsItAndWarnsFarAboveTheUnit) {
  NullProgress progress;
  CancelToken cancel;
  const auto backend = makeCpuBackend();
  SearchParams params;
  params.method = SearchMethod::Exact;
  // White frames: measured, in the note, no warning.
  const FilteredCube white = noiseCube(0.0, 4);
  const SearchResult a = searchWithMethod(*backend, white, grid(3, 0.5), params, progress, cancel);
  ASSERT_TRUE(a.statisticNoise.measured());
  EXPECT_NEAR(a.statisticNoise.scale, 1.0, 4.0 * a.statisticNoise.standardError);
  EXPECT_NE(a.backendNote.find(statisticNoiseNote(a.statisticNoise)), std::string::npos) << a.backendNote;
  EXPECT_TRUE(a.warnings.empty());
  // A static pattern of sigma_F / 4 searched at velocity 0 only: sqrt(2) x the unit, a warning.
  const FilteredCube patterned = noiseCube(kSigma / 4.0, 7);
  const SearchResult b = searchWithMethod(*backend, patterned, grid(1, 0.5), params, progress, cancel);
  ASSERT_TRUE(b.statisticNoise.measured());
  EXPECT_NEAR(b.statisticNoise.scale, std::sqrt(2.0), 4.0 * b.statisticNoise.standardError);
  ASSERT_EQ(b.warnings.size(), 1u);
  EXPECT_NE(b.warnings[0].find("the search statistic's noise is 1.4"), std::string::npos) << b.warnings[0];
}

TEST(StatisticNoise, TheNoteSaysWhatWasMeasured) {
  StatisticNoise n;
  EXPECT_NE(statisticNoiseNote(n).find("not measured"), std::string::npos);
  n.scale = 1.0742;
  n.standardError = 0.0054;
  n.mean = -0.0391;
  n.cells = 20000;
  EXPECT_EQ(
      statisticNoiseNote(n),
      "search statistic's noise on this cube: 1.074 +- 0.005 of the unit sigma_F sqrt(N_in), mean -0.039 "
      "(20000 random cells, 3-sigma clipped; the paper's Prob_false assumes 1 and 0)");
}

}  // namespace
}  // namespace st::search

// Statistical behaviour of the exact search (slow: many searches). Label "slow".
//
// Completeness against injected SNR: a point source moving exactly along a grid velocity with integer
// shifts adds `a` to one pixel per frame, so its cell's SNR is a sqrt(N) / sigma + N(0, 1). The
// matched-filter expectation is P(detect) = Q(threshold - SNR): ~50% at the threshold, 97.7% two sigma
// above, 2.3% two below (a little more where a neighbouring noise cell wins instead). Checked within 10
// percentage points. Pure noise: the false-alarm count over many cubes against Prob_false, within 20%.
#include <gtest/gtest.h>

#include <cstdio>
#include <random>

#include "search_test_cubes.hpp"
#include "st/search/cpu_backend.hpp"
#include "st/search/ipsa.hpp"
#include "st/stats/false_alarm.hpp"

namespace st::search {
namespace {

double completeness(double snr, int injections, unsigned seed) {
  constexpr int kW = 40, kH = 40, kN = 25;
  auto backend = makeCpuBackend();
  NullProgress progress;
  CancelToken cancel;
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> pos(8, 31), vel(0, 6);
  int found = 0;
  for (int i = 0; i < injections; ++i) {
    FilteredCube fc;
    fc.frames = test::noiseCube(kW, kH, test::unevenTimes(kN, 0.4, seed + i), 1.0, seed * 7919 + i);
    fc.sigmaF = 1.0;
    fc.psfFwhmPx = 1.0;
    const VelocityGrid grid{{0, 0}, 1.0 / fc.frames.timeSpanS(), 7, 7};
    const int x = pos(rng), y = pos(rng), ivx = vel(rng), ivy = vel(rng);
    const Velocity v = grid.at(ivx, ivy);
    const std::vector<double> dt = fc.frames.timeOffsetsS();
    const float a = static_cast<float>(snr / std::sqrt(double(kN)));
    for (int n = 0; n < kN; ++n) {
      fc.frames.frame(n)[(y + ipsaShift(v.vy, dt[n])) * kW + x + ipsaShift(v.vx, dt[n])] += a;
    }
    SearchParams params;
    params.snrThreshold = 7.0;
    const SearchResult r = backend->search(fc, grid, params, progress, cancel);
    // Movers and static sources alike: the grid's centre cells are within one FWHM over the span of the
    // sky rate (0 here), and an object there is set aside as static, still found.
    bool hit = false;
    for (const auto* list : {&r.candidates, &r.staticSources})
      for (const Candidate& c : *list)
        hit = hit || (std::abs(c.x - x) <= 1 && std::abs(c.y - y) <= 1 && std::abs(c.ivx - ivx) <= 1 &&
                      std::abs(c.ivy - ivy) <= 1);
    found += hit;
  }
  return static_cast<double>(found) / injections;
}

TEST(SearchSlow, CompletenessFollowsMatchedFilterExpectation) {
  const double at7 = completeness(7.0, 300, 1);
  const double at9 = completeness(9.0, 200, 2);
  const double at5 = completeness(5.0, 200, 3);
  std::printf("completeness at injected SNR 5, 7, 9 (threshold 7): %.3f %.3f %.3f\n", at5, at7, at9);
  EXPECT_NEAR(at7, 0.5, 0.10);
  EXPECT_GE(at9, 0.977 - 0.10);
  EXPECT_NEAR(at5, 0.023, 0.10);
}

TEST(SearchSlow, PureNoiseFalseAlarmsFollowProbFalse) {
  // 20 cubes of 128^2 px, 24 frames, 11 x 11 velocities 2 px apart over the span, threshold 3.5:
  // expected 20 x 128^2 x 121 x Q(3.5) = 9234 cells above.
  auto backend = makeCpuBackend();
  NullProgress progress;
  CancelToken cancel;
  double count = 0.0, expected = 0.0;
  for (unsigned s = 0; s < 20; ++s) {
    FilteredCube fc;
    fc.frames = test::noiseCube(128, 128, test::unevenTimes(24, 0.5, s), 1.0, 1000 + s);
    fc.sigmaF = 1.0;
    fc.psfFwhmPx = 1.0;
    SearchParams params;
    params.snrThreshold = 3.5;
    params.minFrameFraction = 0.0;
    const SearchResult r = backend->search(fc, VelocityGrid{{0, 0}, 2.0 / fc.frames.timeSpanS(), 11, 11},
                                           params, progress, cancel);
    count += static_cast<double>(r.cellsAboveThreshold);
    expected += stats::expectedFalseAlarms(3.5, r.trials.total());
  }
  EXPECT_NEAR(expected, 20.0 * 128 * 128 * 121 * stats::tailProbability(3.5), 1e-6);
  std::printf("noise cells above 3.5: %.0f, Prob_false expects %.1f\n", count, expected);
  EXPECT_NEAR(count / expected, 1.0, 0.2);
}

}  // namespace
}  // namespace st::search

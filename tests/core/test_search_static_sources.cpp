// The static-source rule (search_run.hpp: trackSpanS, setAsideStaticSources): a candidate that moves less
// than one PSF FWHM against the stars over the frames that hold its track is set aside as static. Oracle:
// the tracks' frames counted by hand. The field drifts 5 px/s across a 100 x 50 px image, 41 frames at
// t - t_ref = -20 ... 20 s, FWHM 3 px: over the whole 40 s span the limit is 0.075 px/s, but a source that
// the drift carries across the image is inside for 18-19 s, where the limit is ~0.16 px/s (simulator seed
// 66's partial-span star was found 0.14 px/s off the sky rate, above the whole span's 0.13 px/s).
#include <gtest/gtest.h>

#include <vector>

#include "st/search/search_run.hpp"

namespace st::search {
namespace {

constexpr double kFwhm = 3.0;

TrackFrames driftingFrames() {
  TrackFrames f;
  for (int n = -20; n <= 20; ++n)
    f.dtS.push_back(n);
  f.width = 100;
  f.height = 50;
  return f;
}

Candidate at(int x, int y, double vx, double vy) {
  Candidate c;
  c.x = x;
  c.y = y;
  c.v = {vx, vy};
  c.snr = 10.0;
  return c;
}

TEST(StaticSources, TrackSpanCountsTheFramesThatHoldTheTrack) {
  const TrackFrames f = driftingFrames();
  // x = 50 + 5.2 dt is in [0, 100) for dt in [-9.6, 9.6]: frames -9 ... 9.
  EXPECT_DOUBLE_EQ(trackSpanS(at(50, 20, 5.2, 0.0), f), 18.0);
  // x = 10 + round(5.12 dt): dt = -2 gives 0 (inside), -3 gives -5 (outside); dt = 17 gives 97 (inside), 18
  // gives 102 (outside): frames -2 ... 17.
  EXPECT_DOUBLE_EQ(trackSpanS(at(10, 20, 5.12, 0.0), f), 19.0);
  // A slow track stays in for the whole span; a row outside the image holds nothing.
  EXPECT_DOUBLE_EQ(trackSpanS(at(50, 20, 0.1, 0.0), f), 40.0);
  EXPECT_DOUBLE_EQ(trackSpanS(at(50, 60, 0.0, 0.0), f), 0.0);
  // One frame inside: no span.
  EXPECT_DOUBLE_EQ(trackSpanS(at(50, 20, 200.0, 0.0), f), 0.0);
}

TEST(StaticSources, RegistrationOffsetsMoveTheSamples) {
  TrackFrames f = driftingFrames();
  f.offsets.assign(f.dtS.size(), PixelOffset{});
  for (std::size_t n = 0; n < f.dtS.size(); ++n)
    if (f.dtS[n] > 0.0) f.offsets[n].x = 5.0;  // a dither of 5 px after t_ref
  // x = 97 at rest: inside (97) up to dt = 0, outside (102) after.
  EXPECT_DOUBLE_EQ(trackSpanS(at(97, 20, 0.0, 0.0), f), 20.0);
}

TEST(StaticSources, LimitIsOneFwhmOverTheTracksOwnFrames) {
  const TrackFrames f = driftingFrames();
  const Velocity sky{5.0, 0.0};
  SearchResult r;
  r.candidates = {
      at(10, 20, 5.12, 0.0),   // 0.12 px/s off over 19 s: 2.3 px < 3 px, static (a mover over the whole span)
      at(50, 20, 5.12, 0.05),  // 0.13 px/s over 18 s: 2.3 px, static
      at(50, 30, 5.2, 0.0),    // 0.2 px/s over 18 s: 3.6 px, a mover
      at(60, 10, 5.0, 0.0),    // the sky rate itself
  };
  setAsideStaticSources(r, kFwhm, f, sky);
  ASSERT_EQ(r.candidates.size(), 1u);
  EXPECT_EQ(r.candidates[0].x, 50);
  EXPECT_EQ(r.candidates[0].y, 30);
  ASSERT_EQ(r.staticSources.size(), 3u);
  EXPECT_EQ(r.staticSources[0].x, 10);  // in their order
  EXPECT_EQ(r.staticSources[2].x, 60);
}

TEST(StaticSources, AFieldThatStaysInKeepsTheWholeSpansLimit) {
  TrackFrames f = driftingFrames();
  const Velocity sky{0.0, 0.0};
  SearchResult r;
  r.candidates = {at(50, 20, 0.07, 0.0), at(50, 30, 0.08, 0.0), at(20, 30, 0.0, -0.074)};
  setAsideStaticSources(r, kFwhm, f, sky);  // 3 px / 40 s = 0.075 px/s
  ASSERT_EQ(r.candidates.size(), 1u);
  EXPECT_DOUBLE_EQ(r.candidates[0].v.vx, 0.08);
  EXPECT_EQ(r.staticSources.size(), 2u);
  // A track in one frame only takes the whole span's limit: 0.2 px/s is a mover.
  SearchResult one;
  one.candidates = {at(50, 20, 200.2, 0.0)};
  setAsideStaticSources(one, kFwhm, f, Velocity{200.0, 0.0});
  EXPECT_EQ(one.candidates.size(), 1u);
}

}  // namespace
}  // namespace st::search

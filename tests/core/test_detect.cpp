// Static sources (paper §4.3): stars found in the sky-rate stack and zeroed along the sky motion, the sky
// rate measured from the stars, the moving object left alone.
#include <gtest/gtest.h>

#include <cmath>

#include "st/detect/hot_pixels.hpp"
#include "st/detect/moving_mask.hpp"
#include "st/detect/sky_rate.hpp"
#include "st/detect/sky_stack.hpp"
#include "st/detect/static_sources.hpp"
#include "st/stats/background.hpp"
#include "synthetic_frames.hpp"

namespace st::detect {
namespace {

test::SynthScene scene(Velocity sky) {
  test::SynthScene s;
  s.skyRate = sky;
  s.stars = {{30.0, 25.0, 400.0}, {70.3, 40.6, 12.0}, {55.0, 15.0, 60.0}, {15.2, 30.7, 2000.0}};
  return s;
}

const Star* nearest(const std::vector<Star>& stars, double x, double y) {
  const Star* best = nullptr;
  double bd = 1e9;
  for (const auto& s : stars) {
    const double d = std::hypot(s.x - x, s.y - y);
    if (d < bd) bd = d, best = &s;
  }
  return bd < 1.0 ? best : nullptr;
}

TEST(MovingMask, FollowsTheSkyRate) {
  const std::vector<double> dt = {-10.0, 0.0, 10.0};
  MovingMask m(50, 40, dt, {0.5, -0.2});
  m.set(20, 20);
  EXPECT_TRUE(m.covers(1, 20, 20));
  EXPECT_TRUE(m.covers(0, 15, 22));  // 20 + 0.5 * -10, 20 - 0.2 * -10
  EXPECT_TRUE(m.covers(2, 25, 18));
  EXPECT_FALSE(m.covers(2, 20, 20));
  // The canvas reaches positions that only some frames see.
  m.set(-4, 10);
  EXPECT_TRUE(m.covers(2, 1, 8));
  m.dilate(2);
  // Two discs of radius 2 (13 px each); the one at x = -4 loses its leftmost pixel to the canvas edge (x0 =
  // -5).
  EXPECT_EQ(m.x0(), -5);
  EXPECT_EQ(m.count(), 25u);
}

// dilate() equals the brute-force disc (every canvas pixel within `radius`, di^2 + dj^2 <= radius^2, of a set
// one) on random masks from sparse to dense, at every radius 1-9, near and at the canvas edges: the oracle
// for any faster dilation.
TEST(MovingMask, DilateEqualsTheBruteForceDisc) {
  const std::vector<double> dt = {-30.0, 0.0, 25.0};
  std::uint32_t state = 12345;
  auto next = [&state] { return state = state * 1664525u + 1013904223u; };
  for (const double density : {0.002, 0.03, 0.3}) {
    for (int radius = 1; radius <= 9; ++radius) {
      MovingMask m(61, 29, dt, {0.7, -0.2});
      for (int j = 0; j < m.canvasHeight(); ++j)
        for (int i = 0; i < m.canvasWidth(); ++i)
          if (static_cast<double>(next() % 100000) / 100000.0 < density) m.set(m.x0() + i, m.y0() + j);
      const std::vector<std::uint8_t> before = m.canvas();
      const int cw = m.canvasWidth(), ch = m.canvasHeight();
      std::vector<std::uint8_t> expected(before.size(), 0);
      for (int j = 0; j < ch; ++j)
        for (int i = 0; i < cw; ++i) {
          if (!before[static_cast<std::size_t>(j) * cw + i]) continue;
          for (int dj = -radius; dj <= radius; ++dj)
            for (int di = -radius; di <= radius; ++di)
              if (di * di + dj * dj <= radius * radius && i + di >= 0 && i + di < cw && j + dj >= 0 && j + dj < ch)
                expected[static_cast<std::size_t>(j + dj) * cw + (i + di)] = 1;
        }
      m.dilate(radius);
      ASSERT_EQ(m.canvas(), expected) << "density " << density << " radius " << radius;
    }
  }
}

// coveredRow is covers() for a whole row: every frame, every row (in and off the canvas), registration
// offsets included.
TEST(MovingMask, CoveredRowEqualsCoversPixelByPixel) {
  const std::vector<double> dt = {-20.0, -5.0, 0.0, 7.0, 20.0};
  const std::vector<PixelOffset> offsets = {{3.0, -2.0}, {0.0, 0.0}, {-1.4, 6.2}, {12.0, 1.0}, {-9.0, -7.0}};
  MovingMask m(37, 23, dt, {1.3, -0.6}, offsets);
  for (int y = -40; y < 60; y += 3)
    for (int x = -50; x < 80; x += 5)
      if ((x * 7 + y * 3) % 4 == 0) m.set(x, y);
  m.dilate(1);
  std::vector<std::uint8_t> row(37);
  for (std::size_t n = 0; n < dt.size(); ++n)
    for (int y = 0; y < 23; ++y) {
      m.coveredRow(n, y, row.data());
      for (int x = 0; x < 37; ++x)
        ASSERT_EQ(row[x] != 0, m.covers(n, x, y)) << "frame " << n << " (" << x << ", " << y << ")";
    }
}

class StaticSourcesTest : public ::testing::TestWithParam<bool> {};

TEST_P(StaticSourcesTest, FindsStarsZeroesThemAndKeepsTheMovingObject) {
  const bool drifting = GetParam();
  const Velocity sky = drifting ? Velocity{0.3, -0.2} : Velocity{};
  auto sc = scene(sky);
  FrameCube cube = sc.make();
  NullProgress p;
  CancelToken c;
  const stats::ClipStats global = stats::globalBackground(cube);
  EXPECT_NEAR(global.mean, sc.background, 0.3);
  Velocity rate = sky;
  if (drifting) {
    const SkyRate measured = measureSkyRate(cube, global.mean, global.sigma, {}, c);
    ASSERT_TRUE(measured.reliable) << measured.note;
    EXPECT_NEAR(measured.rate.vx, sky.vx, 0.02) << measured.note;
    EXPECT_NEAR(measured.rate.vy, sky.vy, 0.02) << measured.note;
    rate = measured.rate;
  }
  const StaticSources found = findStaticSources(cube, rate, global.mean, {}, p, c);
  for (const auto& s : sc.stars) {
    const Star* f = nearest(found.stars, s.x, s.y);
    ASSERT_NE(f, nullptr) << "star at " << s.x << "," << s.y << " not found";
    EXPECT_NEAR(f->x, s.x, 0.25);
    EXPECT_NEAR(f->y, s.y, 0.25);
    EXPECT_GE(f->snr, 7.0);
    // Flux per frame within the grown footprint: most of the Gaussian's 2 pi s^2 peak.
    const double total = s.peak * 2.0 * M_PI * std::pow(3.0 / 2.354820045, 2);
    EXPECT_GT(f->flux, 0.7 * total);
    EXPECT_LT(f->flux, 1.15 * total);
  }
  EXPECT_EQ(found.stars.size(), sc.stars.size());  // no false detection, the moving object not a star

  const FrameCube before = cube;
  stats::Background bg = stats::estimateBackground(cube, {}, &found.mask, p, c);
  EXPECT_NEAR(bg.sigmaN, sc.sigma, 0.03 * sc.sigma);
  stats::subtractBackground(cube, bg.level, p, c);
  zeroMasked(cube, found.mask, p, c);
  const auto single = zeroSingleFrameSources(cube, bg.sigma, bg.sigmaN, 7.0, 3, p, c);
  const auto dt = cube.timeOffsetsS();
  std::size_t objectPixelsKept = 0, starResidue = 0;
  for (std::size_t n = 0; n < cube.frameCount(); ++n) {
    const auto [ox, oy] = sc.objectAt(dt[n]);
    for (int y = static_cast<int>(oy) - 1; y <= static_cast<int>(oy) + 2; ++y)
      for (int x = static_cast<int>(ox) - 1; x <= static_cast<int>(ox) + 2; ++x) {
        if (x < 0 || y < 0 || x >= cube.width() || y >= cube.height()) continue;
        ASSERT_NE(cube.frame(n)[y * cube.width() + x], 0.0f) << "object pixel zeroed in frame " << n;
        EXPECT_NEAR(cube.frame(n)[y * cube.width() + x],
                    before.frame(n)[y * cube.width() + x] - bg.level.at(x, y), 1e-3);
        ++objectPixelsKept;
      }
    for (const auto& s : sc.stars) {  // star centres are zero in every frame
      const int x = static_cast<int>(std::lround(s.x + sky.vx * dt[n]));
      const int y = static_cast<int>(std::lround(s.y + sky.vy * dt[n]));
      if (x >= 0 && y >= 0 && x < cube.width() && y < cube.height())
        starResidue += cube.frame(n)[y * cube.width() + x] != 0.0f;
    }
  }
  EXPECT_GT(objectPixelsKept, 500u);
  EXPECT_EQ(starResidue, 0u);
  std::size_t seeds = 0;
  for (auto s : single.seedsPerFrame)
    seeds += s;
  EXPECT_LT(seeds, 3u);  // stars already gone; pure noise rarely reaches 7 sigma
}

INSTANTIATE_TEST_SUITE_P(TrackedAndDrifting, StaticSourcesTest, ::testing::Values(false, true));

TEST(SingleFrameSources, BrightTransientIsZeroedInItsFrameOnly) {
  FrameCube cube(40, 30, 3);
  cube.frame(1)[15 * 40 + 20] = 100.0f;
  NullProgress p;
  CancelToken c;
  const auto r = zeroSingleFrameSources(cube, Image(), 5.0, 7.0, 2, p, c);
  EXPECT_EQ(r.seedsPerFrame[1], 1u);
  EXPECT_EQ(r.seedsPerFrame[0], 0u);
  EXPECT_EQ(cube.frame(1)[15 * 40 + 20], 0.0f);
}

// Pixels without a measured background are zeroed in every frame unless a mover's track (the keep mask,
// carried with the sky rate) covers them in some frame; measured pixels are untouched. Oracle: the flags.
TEST(UnmeasuredPixels, ZeroedInEveryFrameExceptOnMoverTracks) {
  const std::vector<double> dt = {-2.0, -1.0, 0.0, 1.0, 2.0};
  FrameCube cube(40, 30, dt.size());
  for (auto& v : cube.pixels())
    v = 5.0f;
  std::vector<std::uint8_t> unmeasured(cube.framePixels(), 0);
  unmeasured[10 * 40 + 10] = 1;  // e.g. a halo pixel at a mask edge
  unmeasured[12 * 40 + 22] = 1;  // on the mover's track in frame 4 only
  MovingMask keep(40, 30, dt, {1.0, 0.0});
  keep.set(20, 12);  // reference position: frame n sees it at x = 20 + round(dt_n)
  const std::size_t zeroed = zeroUnmeasured(cube, unmeasured, keep);
  EXPECT_EQ(zeroed, 1u);
  for (std::size_t n = 0; n < cube.frameCount(); ++n) {
    EXPECT_EQ(cube.frame(n)[10 * 40 + 10], 0.0f) << "frame " << n;
    EXPECT_EQ(cube.frame(n)[12 * 40 + 22], 5.0f) << "frame " << n;
    EXPECT_EQ(cube.frame(n)[5 * 40 + 5], 5.0f) << "frame " << n;
  }
  EXPECT_EQ(zeroUnmeasured(cube, unmeasured, keep), 0u) << "already 0: not counted again";
}

TEST(HotPixels, FoundAndStarsAreNot) {
  auto sc = scene({});  // tracked: the stars are as persistent as a hot pixel, but not as sharp
  FrameCube cube = sc.make();
  for (std::size_t n = 0; n < cube.frameCount(); ++n)
    cube.frame(n)[50 * sc.width + 10] += 80.0f;
  CancelToken c;
  const stats::ClipStats g = stats::globalBackground(cube);
  const auto hot = findHotPixels(cube, g.mean, g.sigma, {}, c);
  ASSERT_EQ(hot.size(), 1u);
  EXPECT_EQ(hot[0], static_cast<std::size_t>(50 * sc.width + 10));
  EXPECT_EQ(maskPixelsInAllFrames(cube, hot), 1u);
  EXPECT_TRUE(cube.isMasked(7, 10, 50));
  EXPECT_FALSE(cube.isMasked(7, 30, 25));
}

TEST(SkyStack, CountsOnlyContributingFrames) {
  FrameCube cube(10, 8, 5);
  for (std::size_t n = 0; n < 5; ++n) {
    cube.info()[n].mjdMid = 60000.0 + n / 86400.0;
    std::fill(cube.frame(n), cube.frame(n) + 80, 1.0f);
  }
  NullProgress p;
  CancelToken c;
  const SkyStack s = stackAtSkyRate(cube, {1.0, 0.0}, 0.0, p, c);
  EXPECT_EQ(s.mean.width, 14);        // shifts -2..2
  EXPECT_EQ(s.count.at(0, 0), 1.0f);  // reference x = -2: only the last frame sees it
  EXPECT_EQ(s.count.at(7, 3), 5.0f);
  EXPECT_FLOAT_EQ(s.mean.at(0, 0), 1.0f);
}

// A star below SNR 7 per pixel in the sky-rate stack but far above it after the PSF filter (what the velocity
// search sees): found and masked with filteredDetection (not without), while a moving object bright enough
// to pass the filtered threshold in the sky-rate stack (a streak there) is not taken for a star (its halves
// disagree) and stays unmasked. Oracle: per-pixel stack SNR = peak sqrt(N) / sigma = 5.4 and matched-filter
// SNR = peak sqrt(N) sqrt(sum g^2) / sigma ~ 12 for a Gaussian of FWHM 3 (sum g^2 = pi s^2).
TEST(StaticSources, FaintStarsFoundAfterThePsfFilterSlowObjectsNot) {
  test::SynthScene sc;
  sc.frames = 60;
  sc.stars = {{60.0, 30.0, 3.5}};
  sc.objPeak = 14.0;  // a 51 px streak in the stack: filtered SNR ~ 12 at its centre, moving
  FrameCube cube = sc.make();
  NullProgress p;
  CancelToken c;
  const stats::ClipStats global = stats::globalBackground(cube);
  StaticSourceParams off;
  off.filteredDetection = false;
  EXPECT_EQ(nearest(findStaticSources(cube, {}, global.mean, off, p, c).stars, 60.0, 30.0), nullptr)
      << "the star is above SNR 7 per pixel: the test does not test the filtered detection";
  const StaticSources found = findStaticSources(cube, {}, global.mean, {}, p, c);
  const Star* star = nearest(found.stars, 60.0, 30.0);
  ASSERT_NE(star, nullptr) << "faint star not found after the PSF filter";
  EXPECT_LT(star->snr, 7.0);
  EXPECT_GT(star->filteredSnr, 8.0);
  EXPECT_LT(star->filteredSnr, 16.0);
  EXPECT_TRUE(found.mask.covers(0, 60, 30));
  const auto dt = cube.timeOffsetsS();
  std::size_t covered = 0;
  for (std::size_t n = 0; n < cube.frameCount(); ++n) {
    const auto [ox, oy] = sc.objectAt(dt[n]);
    const int x = static_cast<int>(std::lround(ox)), y = static_cast<int>(std::lround(oy));
    if (x >= 0 && y >= 0 && x < sc.width && y < sc.height) covered += found.mask.covers(n, x, y);
  }
  EXPECT_EQ(covered, 0u) << "the moving object was taken for a static source";
  EXPECT_EQ(found.stars.size(), 1u);
}

// The PSF's catalogue (catalogueOnly, issue 16: what the pipeline runs before the PSF fit, the whole search
// then running once at the fitted FWHM) against the whole search as the oracle, in a drifting field with a
// bright slow mover (3 px over the span relative to the stars, a star-like short streak per pixel): the same
// per-pixel stars (the whole search's stars with SNR >= 7; positions within 0.05 px, fluxes within 2%; its
// analysis leaves the filtered blobs out of the second mesh background, so not to every digit), the faint
// star seen only after the filter not among them, the mover left out of both catalogues alike, and no mask.
TEST(StaticSources, CatalogueOnlyIsTheWholeSearchsPerPixelStarsWithoutMasks) {
  test::SynthScene sc = scene({0.3, -0.2});
  sc.stars.push_back({45.0, 60.0, 3.5});  // SNR ~5 per pixel in the stack, ~11 after the filter
  sc.objX = 75.0, sc.objY = 20.0;
  sc.objRate = {0.35, -0.2};  // 0.05 px/s off the stars: 3 px over the 60 s
  sc.objPeak = 40.0;
  FrameCube cube = sc.make();
  NullProgress p;
  CancelToken c;
  const stats::ClipStats global = stats::globalBackground(cube);
  const Velocity rate{0.3, -0.2};
  const StaticSources whole = findStaticSources(cube, rate, global.mean, {}, p, c);
  StaticSourceParams only;
  only.catalogueOnly = true;
  const StaticSources cat = findStaticSources(cube, rate, global.mean, only, p, c);
  ASSERT_EQ(whole.movers.size(), 1u) << "the scene's mover is not one: the test does not test leaving it out";
  ASSERT_EQ(cat.movers.size(), 1u);
  EXPECT_NEAR(cat.movers[0].x, whole.movers[0].x, 0.05);
  EXPECT_NEAR(cat.movers[0].y, whole.movers[0].y, 0.05);
  ASSERT_NE(nearest(whole.stars, 45.0, 60.0), nullptr) << "the faint star is not found after the filter";
  EXPECT_EQ(nearest(cat.stars, 45.0, 60.0), nullptr);
  std::size_t perPixel = 0;
  for (const Star& w : whole.stars) {
    if (w.snr < StaticSourceParams{}.snrThreshold) continue;
    ++perPixel;
    const Star* s = nearest(cat.stars, w.x, w.y);
    ASSERT_NE(s, nullptr) << "star at " << w.x << "," << w.y << " not in the PSF's catalogue";
    EXPECT_NEAR(s->x, w.x, 0.05);
    EXPECT_NEAR(s->y, w.y, 0.05);
    EXPECT_NEAR(s->flux, w.flux, 0.02 * w.flux);
    EXPECT_EQ(s->saturated, w.saturated);
  }
  EXPECT_EQ(perPixel, sc.stars.size() - 1);
  EXPECT_EQ(cat.stars.size(), perPixel);
  EXPECT_EQ(cat.mask.count(), 0u);
  EXPECT_EQ(cat.subtractRegion.count(), 0u);
  EXPECT_GT(whole.mask.count(), 0u);
}

// What a search keeps in the shared SkyStackCache (the thirds less their mesh backgrounds, the first analysis
// pass: SkyStackCache::derived) changes nothing: the PSF's catalogue at FWHM 3 then the whole search at 2.2 on
// one cache give the fresh whole search at 2.2 to every bit (stars, movers, the three masks, the stack noise),
// and a search with another mesh on that cache gives its own fresh result (the mesh is in the key).
TEST(StaticSources, WhatTheCacheKeepsChangesNothing) {
  test::SynthScene sc = scene({0.3, -0.2});
  sc.stars.push_back({45.0, 60.0, 3.5});
  sc.objX = 75.0, sc.objY = 20.0;
  sc.objRate = {0.35, -0.2};
  sc.objPeak = 40.0;
  const FrameCube cube = sc.make();
  NullProgress p;
  CancelToken c;
  const stats::ClipStats global = stats::globalBackground(cube);
  const Velocity rate{0.3, -0.2};
  const auto same = [](const StaticSources& a, const StaticSources& b, const char* what) {
    ASSERT_EQ(a.stars.size(), b.stars.size()) << what;
    for (std::size_t k = 0; k < a.stars.size(); ++k) {
      const Star &u = a.stars[k], &v = b.stars[k];
      EXPECT_TRUE(u.x == v.x && u.y == v.y && u.flux == v.flux && u.peak == v.peak && u.snr == v.snr &&
                  u.filteredSnr == v.filteredSnr && u.pixels == v.pixels && u.saturated == v.saturated &&
                  u.bleedColumns == v.bleedColumns && u.motionXPx == v.motionXPx && u.motionYPx == v.motionYPx)
          << what << ": star " << k;
    }
    ASSERT_EQ(a.movers.size(), b.movers.size()) << what;
    for (std::size_t k = 0; k < a.movers.size(); ++k)
      EXPECT_TRUE(a.movers[k].x == b.movers[k].x && a.movers[k].y == b.movers[k].y &&
                  a.movers[k].v.vx == b.movers[k].v.vx && a.movers[k].shiftPx == b.movers[k].shiftPx)
          << what << ": mover " << k;
    EXPECT_EQ(a.mask.canvas(), b.mask.canvas()) << what;
    EXPECT_EQ(a.moverMask.canvas(), b.moverMask.canvas()) << what;
    EXPECT_EQ(a.subtractRegion.canvas(), b.subtractRegion.canvas()) << what;
    EXPECT_EQ(a.stackNoise, b.stackNoise) << what;
  };
  StaticSourceParams at22;
  at22.psfFwhmPx = 2.2;
  StaticSourceParams catalogue;
  catalogue.catalogueOnly = true;
  SkyStackCache shared;
  (void)findStaticSources(cube, rate, global.mean, catalogue, p, c, &shared);
  const StaticSources kept = findStaticSources(cube, rate, global.mean, at22, p, c, &shared);
  const StaticSources fresh = findStaticSources(cube, rate, global.mean, at22, p, c);
  ASSERT_FALSE(fresh.movers.empty()) << "the scene's mover is not one: the thirds' part is not tested";
  same(kept, fresh, "the catalogue then the search on one cache");
  StaticSourceParams mesh16 = at22;
  mesh16.meshPx = 16;
  same(findStaticSources(cube, rate, global.mean, mesh16, p, c, &shared),
       findStaticSources(cube, rate, global.mean, mesh16, p, c), "another mesh on that cache");
}

}  // namespace
}  // namespace st::detect

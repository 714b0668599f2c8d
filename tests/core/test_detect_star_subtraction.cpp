// Star subtraction in a drifting field (issue 14): the sky-registered template removes the stars to the
// noise, at sub-pixel offsets, and keeps a slow mover that crosses a star's wings.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "st/detect/moving_mask.hpp"
#include "st/detect/star_subtraction.hpp"
#include "st/psf/moffat.hpp"
#include "synthetic_frames.hpp"

namespace st::detect {
namespace {

TEST(StarSubtraction, LanczosWeightsSampleTheGridAndAreNormalised) {
  double w[6];
  EXPECT_EQ(lanczos3Weights(0.0, w), -2);
  for (int k = 0; k < 6; ++k)
    EXPECT_NEAR(w[k], k == 2 ? 1.0 : 0.0, 1e-12);
  for (double f : {-0.5, -0.3, 0.1, 0.45}) {
    const int o = lanczos3Weights(f, w);
    EXPECT_EQ(o, static_cast<int>(std::floor(f)) - 2);
    // A Gaussian of FWHM 3.5 px (sigma 1.49) sampled on the grid, interpolated at f: within 0.5% of its
    // peak.
    double s = 0.0, v = 0.0;
    for (int k = 0; k < 6; ++k) {
      s += w[k];
      v += w[k] * std::exp(-0.5 * (o + k) * (o + k) / (1.486 * 1.486));
    }
    EXPECT_NEAR(s, 1.0, 1e-12);
    EXPECT_NEAR(v, std::exp(-0.5 * f * f / (1.486 * 1.486)), 0.005) << "at " << f;
  }
}

// 120 frames of 160 x 96, stars drifting at (1.37, 0.23) px/s (fractional shifts every frame), FWHM 3.5 px,
// noise 5 counts; a faint object moving 0.4 px/s relative to the stars passes through a bright star's wings.
struct Field {
  test::SynthScene scene;
  Field(bool object, std::uint32_t seed) {
    scene.width = 160;
    scene.height = 96;
    scene.frames = 120;
    scene.cadenceS = 1.0;
    scene.background = 0.0;
    scene.sigma = 5.0;
    scene.fwhm = 3.5;
    scene.skyRate = {1.37, 0.23};
    scene.stars = {{80.0, 48.0, 2000.0}, {40.0, 30.0, 300.0}, {120.0, 70.0, 60.0}};
    scene.withObject = object;
    scene.objX = 80.0 - 12.0;  // crosses the bright star's wings 4 px below its centre
    scene.objY = 52.0;
    scene.objRate = {1.37 + 0.4, 0.23};
    scene.objPeak = 10.0;
    scene.seed = seed;
  }
};

MovingMask starRegion(const FrameCube& cube, const test::SynthScene& s) {
  MovingMask m(cube.width(), cube.height(), cube.timeOffsetsS(), s.skyRate);
  for (const auto& st : s.stars)
    for (int dy = -12; dy <= 12; ++dy)
      for (int dx = -12; dx <= 12; ++dx)
        if (dx * dx + dy * dy <= 144) m.set(static_cast<int>(st.x) + dx, static_cast<int>(st.y) + dy);
  return m;
}

// Residual rms within 6 px of a star, over the frames that see it whole (`samples`: how many pixels).
double residualRmsNear(const FrameCube& cube, const test::SynthScene& scene, double sx, double sy,
                       std::size_t* samples = nullptr) {
  const auto dt = cube.timeOffsetsS();
  double ss = 0.0;
  std::size_t n = 0;
  for (std::size_t k = 0; k < cube.frameCount(); ++k) {
    const double cx = sx + scene.skyRate.vx * dt[k], cy = sy + scene.skyRate.vy * dt[k];
    if (cx < 10 || cy < 10 || cx > 150 || cy > 86) continue;
    for (int y = static_cast<int>(cy) - 6; y <= static_cast<int>(cy) + 6; ++y)
      for (int x = static_cast<int>(cx) - 6; x <= static_cast<int>(cx) + 6; ++x) {
        const double v = cube.frame(k)[static_cast<std::size_t>(y) * cube.width() + x];
        ss += v * v;
        ++n;
      }
  }
  if (samples) *samples = n;
  return n ? std::sqrt(ss / n) : 0.0;
}

TEST(StarSubtraction, RemovesDriftingStarsToTheNoise) {
  Field field(false, 3);
  FrameCube cube = field.scene.make();
  NullProgress p;
  CancelToken c;
  const StarSubtraction r = subtractStarTemplate(cube, starRegion(cube, field.scene), nullptr, {}, p, c);
  ASSERT_TRUE(r.applied);
  EXPECT_GT(r.pixelsSubtracted, 0u);
  // Within 6 px of each star, in the frames that see it whole: rms of what is left against the noise.
  for (const auto& st : field.scene.stars) {
    std::size_t n = 0;
    const double rms = residualRmsNear(cube, field.scene, st.x, st.y, &n);
    ASSERT_GT(n, 1000u);
    std::printf("star peak %.0f: residual rms %.2f counts (noise 5)\n", st.peak, rms);
    // The template's own noise adds ~1/sqrt(60) of the variance; interpolation error < 0.3% of the peak
    // (measured 2026-11-25: rms 6.37, 5.06, 5.04 for peaks 2000, 300, 60).
    EXPECT_LT(rms, std::hypot(5.0 * 1.05, 0.003 * st.peak)) << "star at peak " << st.peak;
  }
}

TEST(StarSubtraction, KeepsASlowMoverCrossingAStar) {
  // The same noise with and without the object: the difference after subtraction is what is left of it.
  Field with(true, 5), without(false, 5);
  FrameCube a = with.scene.make(), b = without.scene.make();
  NullProgress p;
  CancelToken c;
  (void)subtractStarTemplate(a, starRegion(a, with.scene), nullptr, {}, p, c);
  (void)subtractStarTemplate(b, starRegion(b, without.scene), nullptr, {}, p, c);
  const auto dt = a.timeOffsetsS();
  double kept = 0.0, injected = 0.0;
  const double s = with.scene.fwhm / 2.354820045;
  for (std::size_t k = 0; k < a.frameCount(); ++k) {
    const auto [ox, oy] = with.scene.objectAt(dt[k]);
    if (ox < 8 || oy < 8 || ox > 152 || oy > 88) continue;
    for (int y = static_cast<int>(oy) - 4; y <= static_cast<int>(oy) + 4; ++y)
      for (int x = static_cast<int>(ox) - 4; x <= static_cast<int>(ox) + 4; ++x) {
        const std::size_t i = static_cast<std::size_t>(y) * a.width() + x;
        kept += a.frame(k)[i] - b.frame(k)[i];
        injected += with.scene.objPeak * std::exp(-0.5 * ((x - ox) * (x - ox) + (y - oy) * (y - oy)) / (s * s));
      }
  }
  std::printf("slow mover across a star: %.1f%% of its flux kept\n", 100.0 * kept / injected);
  EXPECT_GT(kept / injected, 0.95);
  EXPECT_LT(kept / injected, 1.02);
}

// Masked sky positions within 6 px of the bright star (80, 48) and elsewhere.
std::pair<std::size_t, std::size_t> maskedNearBright(const MovingMask& mask) {
  const auto& ex = mask.canvas();
  std::size_t nearBright = 0, elsewhere = 0;
  for (std::size_t i = 0; i < ex.size(); ++i) {
    if (!ex[i]) continue;
    const int x = mask.x0() + static_cast<int>(i) % mask.canvasWidth(),
              y = mask.y0() + static_cast<int>(i) / mask.canvasWidth();
    (std::hypot(x - 80.0, y - 48.0) <= 6.0 ? nearBright : elsewhere) += 1;
  }
  return {nearBright, elsewhere};
}

// With the background's sigma given, sky positions whose residuals vary more than the background are
// whitened: the bright star's core (its 0.2% interpolation error is 4 counts rms against 5 of noise: ratio
// ~1.6) comes down to the noise, the faint stars are left alone (but for chance, at 3 sigma of the ratio's
// scatter). With the old limit (mask above 1.3x) the same positions are masked instead.
TEST(StarSubtraction, ExcessVarianceIsWhitenedAndALargeExcessMasked) {
  Field field(false, 9);
  const Image sigma(field.scene.width, field.scene.height, 5.0f);
  NullProgress p;
  CancelToken c;
  FrameCube cube = field.scene.make();
  const StarSubtraction r = subtractStarTemplate(cube, starRegion(cube, field.scene), &sigma, {}, p, c);
  ASSERT_TRUE(r.applied);
  EXPECT_GT(r.whitenedPositions, 0u);
  // Masked (above 4x): only at the bright star's core, if anywhere (7 positions measured).
  const auto [coreMasked, otherMasked] = maskedNearBright(r.excess);
  EXPECT_EQ(otherMasked, 0u);
  EXPECT_EQ(coreMasked > 0, r.excessPositions > 0);
  const double bright = residualRmsNear(cube, field.scene, 80.0, 48.0),
               mid = residualRmsNear(cube, field.scene, 40.0, 30.0);
  std::printf("whitened %zu positions; residual rms near the bright star %.2f, the 300-count star %.2f (noise 5)\n",
              r.whitenedPositions, bright, mid);
  // Without sigma nothing is whitened: rms 6.37 (RemovesDriftingStarsToTheNoise). Positions are whitened
  // only where their excess is significant (ratio above 1 + 3 sqrt(2 / S), 1.4 for ~100 frames), so the
  // excess variance over the 13 x 13 px box is reduced, not removed: measured 2026-11-26, 5.71 (excess
  // 7.6 counts^2 of 15.6).
  FrameCube plain = field.scene.make();
  (void)subtractStarTemplate(plain, starRegion(plain, field.scene), nullptr, {}, p, c);
  const double before = residualRmsNear(plain, field.scene, 80.0, 48.0);
  EXPECT_LT(bright * bright - 25.0, 0.6 * (before * before - 25.0)) << "before " << before;
  EXPECT_GT(bright, 5.0 * 0.95) << "whitened to the background, not below it";
  EXPECT_LT(mid, 5.0 * 1.05);

  FrameCube old = field.scene.make();
  StarSubtractionParams maskAll;
  maskAll.maxVarianceRatio = 1.3;
  maskAll.excessSignificance = 5.0;
  const StarSubtraction m = subtractStarTemplate(old, starRegion(old, field.scene), &sigma, maskAll, p, c);
  EXPECT_GT(m.excessPositions, 0u);
  const auto [nearBright, elsewhere] = maskedNearBright(m.excess);
  std::printf("masked above 1.3x: %zu positions near the bright star, %zu elsewhere\n", nearBright, elsewhere);
  EXPECT_GT(nearBright, 0u);
  // Chance alone: a position or two of the ~1,300 (each dilated to 5 or 9).
  EXPECT_LE(elsewhere, 18u);
}

TEST(StarSubtraction, NotAppliedWhenNoFrameLiesOutsideTheWindow) {
  Field field(false, 7);
  field.scene.frames = 6;
  FrameCube cube = field.scene.make();
  NullProgress p;
  CancelToken c;
  StarSubtractionParams params;
  params.windowFraction = 1.0;
  const FrameCube before = cube;
  const StarSubtraction r = subtractStarTemplate(cube, starRegion(cube, field.scene), nullptr, params, p, c);
  EXPECT_FALSE(r.applied);
  EXPECT_EQ(cube.pixels(), before.pixels());
}

}  // namespace
}  // namespace st::detect

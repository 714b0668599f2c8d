// Tests of the paper's sigma-clip (§3.1) and the background/noise estimation against brute-force oracles and
// known truth of synthetic frames.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <vector>

#include "st/common/error.hpp"
#include "st/common/frame_cube.hpp"
#include "st/stats/background.hpp"
#include "st/stats/sigma_clip.hpp"
#include "st/stats/strong_signal_cut.hpp"
#include "test_support.hpp"

namespace st::stats {
namespace {

// Brute-force oracle: the paper's steps 1-4 written literally with explicit index sets.
ClipStats literalClip(const std::vector<float>& y, double xi) {
  std::vector<std::size_t> b(y.size());
  std::iota(b.begin(), b.end(), 0);
  ClipStats out;
  for (int it = 1; it < 1000; ++it) {
    double mean = 0.0;
    for (auto i : b)
      mean += y[i];
    mean /= static_cast<double>(b.size());
    double var = 0.0;
    for (auto i : b)
      var += (y[i] - mean) * (y[i] - mean);
    const double sd = std::sqrt(var / static_cast<double>(b.size() - 1));
    std::vector<std::size_t> nb;
    for (std::size_t i = 0; i < y.size(); ++i)
      if (y[i] <= mean + xi * sd) nb.push_back(i);
    out = {mean, sd, b.size(), it, nb == b};
    if (nb == b) break;
    b = nb;
  }
  return out;
}

TEST(SigmaClip, MatchesLiteralPaperAlgorithm) {
  std::mt19937 rng(1);
  std::normal_distribution<float> noise(100.0f, 5.0f);
  std::vector<float> y(5000);
  for (auto& v : y)
    v = noise(rng);
  for (int i = 0; i < 200; ++i)
    y[i * 7] += 30.0f + i;  // signals above the background
  for (double xi : {3.0, 4.0, 5.0}) {
    const ClipStats fast = sigmaClip(y.data(), y.size(), xi);
    const ClipStats ref = literalClip(y, xi);
    EXPECT_TRUE(fast.converged);
    EXPECT_EQ(fast.count, ref.count) << "xi " << xi;
    EXPECT_NEAR(fast.mean, ref.mean, 1e-9 * std::abs(ref.mean));
    EXPECT_NEAR(fast.sigma, ref.sigma, 1e-9 * ref.sigma);
  }
}

TEST(SigmaClip, RemovesSignalsAndRecoversGaussianTruth) {
  std::mt19937 rng(2);
  std::normal_distribution<float> noise(1000.0f, 10.0f);
  std::vector<float> y(200000);
  for (auto& v : y)
    v = noise(rng);
  for (std::size_t i = 0; i < y.size(); i += 50)
    y[i] += 500.0f;  // 2% bright outliers
  const ClipStats c = sigmaClip(y.data(), y.size(), 4.0);
  EXPECT_NEAR(c.mean, 1000.0, 0.1);  // ~4 standard errors of the mean (10 / sqrt(2e5) = 0.022)
  EXPECT_NEAR(c.sigma, 10.0, 0.1);
  EXPECT_LE(c.count, y.size() - y.size() / 50);
}

TEST(SigmaClip, EdgeCasesAreFinite) {
  EXPECT_EQ(sigmaClip(nullptr, 0, 4.0).count, 0u);
  const std::vector<float> same(10, 3.0f);
  const ClipStats c = sigmaClip(same.data(), same.size(), 4.0);
  EXPECT_EQ(c.count, 10u);
  EXPECT_DOUBLE_EQ(c.mean, 3.0);
  EXPECT_DOUBLE_EQ(c.sigma, 0.0);
  const float one = 7.0f;
  EXPECT_DOUBLE_EQ(sigmaClip(&one, 1, 4.0).sigma, 0.0);
}

TEST(SigmaClip, SymmetricClipsBothSides) {
  std::mt19937 rng(3);
  std::normal_distribution<float> noise(0.0f, 1.0f);
  std::vector<float> y(20000);
  for (auto& v : y)
    v = noise(rng);
  for (int i = 0; i < 100; ++i)
    y[i] = (i % 2 ? 50.0f : -50.0f);
  const ClipStats c = sigmaClipSymmetric(y.data(), y.size(), 5.0);
  EXPECT_NEAR(c.sigma, 1.0, 0.03);
  EXPECT_NEAR(c.mean, 0.0, 0.03);
}

// The symmetric clip of more than 65536 values sums its moments per chunk on every core (the stack analyses'
// ~1M values): the same result on 1, 3 and 8 threads, bit for bit, and the literal clip's (long double
// sums over explicit index sets): the same background set, the mean within 1e-12, sigma within 1e-9 (as
// MatchesLiteralPaperAlgorithm). Outliers both ways.
TEST(SigmaClip, SymmetricClipOfManyValuesIsTheSameOnAnyThreadCount) {
  std::mt19937 rng(4);
  std::normal_distribution<float> noise(250.0f, 7.0f);
  std::vector<float> y(1000003);  // 15 full chunks and a partial one
  for (auto& v : y)
    v = noise(rng);
  for (std::size_t i = 0; i < y.size(); i += 97)
    y[i] += (i % 2 ? 400.0f : -300.0f);
  ClipStats one;
  {
    const test::ScopedThreads threads("1");
    one = sigmaClipSymmetric(y.data(), y.size(), 4.0);
  }
  for (const char* n : {"3", "8"}) {
    const test::ScopedThreads threads(n);
    const ClipStats c = sigmaClipSymmetric(y.data(), y.size(), 4.0);
    EXPECT_EQ(c.mean, one.mean) << n << " threads";
    EXPECT_EQ(c.sigma, one.sigma) << n << " threads";
    EXPECT_EQ(c.count, one.count) << n << " threads";
    EXPECT_EQ(c.iterations, one.iterations) << n << " threads";
  }
  // The literal symmetric clip.
  double lo = -1e300, hi = 1e300, mean = 0.0, sd = 0.0;
  std::size_t count = 0, previous = 0;
  for (int it = 0; it < 100; ++it) {
    long double s = 0.0L;
    count = 0;
    for (float v : y)
      if (v >= lo && v <= hi) s += v, ++count;
    mean = static_cast<double>(s / count);
    long double q = 0.0L;
    for (float v : y)
      if (v >= lo && v <= hi) q += (v - static_cast<long double>(mean)) * (v - static_cast<long double>(mean));
    sd = std::sqrt(static_cast<double>(q / (count - 1)));
    if (count == previous) break;
    previous = count;
    lo = mean - 4.0 * sd;
    hi = mean + 4.0 * sd;
  }
  EXPECT_TRUE(one.converged);
  EXPECT_EQ(one.count, count);
  EXPECT_NEAR(one.mean, mean, 1e-12 * std::abs(mean));
  EXPECT_NEAR(one.sigma, sd, 1e-9 * sd);  // the one-pass variance about the first value: ~1e-11 here
  EXPECT_NEAR(one.sigma, 7.0, 0.05);
}

// A cube with a pixel-dependent background (gradient), Gaussian noise, a few moving bright spots.
FrameCube noisyCube(int w, int h, std::size_t nf, double sigma, std::uint32_t seed) {
  FrameCube cube(w, h, nf);
  std::mt19937 rng(seed);
  std::normal_distribution<float> noise(0.0f, static_cast<float>(sigma));
  for (std::size_t n = 0; n < nf; ++n) {
    cube.info()[n].mjdMid = 60000.0 + static_cast<double>(n) / 86400.0;
    float* f = cube.frame(n);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x)
        f[y * w + x] = 500.0f + 0.5f * x + 0.25f * y + noise(rng);
    const int sx = static_cast<int>(n * 3) % w, sy = static_cast<int>(n * 5) % h;
    f[sy * w + sx] += 400.0f;  // a bright moving object: an outlier in each pixel's time series
  }
  return cube;
}

TEST(Background, PerPixelClipEqualsScalarClipOfEachPixel) {
  FrameCube cube = noisyCube(37, 11, 120, 10.0, 4);
  NullProgress p;
  CancelToken c;
  BackgroundParams params;
  params.global.frames = 120;
  const Background bg = estimateBackground(cube, params, nullptr, p, c);
  for (int y = 0; y < cube.height(); ++y) {
    for (int x = 0; x < cube.width(); ++x) {
      // The strong-signal cut relative to the pixel's own lower median.
      std::vector<float> all;
      for (std::size_t n = 0; n < cube.frameCount(); ++n)
        all.push_back(cube.frame(n)[y * cube.width() + x]);
      std::vector<float> sorted = all;
      std::sort(sorted.begin(), sorted.end());
      const double strong = static_cast<double>(sorted[(sorted.size() - 1) / 2]) + 5.0 * bg.global.sigma;
      std::vector<float> s;
      for (const float v : all)
        if (v <= strong) s.push_back(v);
      const ClipStats ref = sigmaClip(s.data(), s.size(), 4.0);
      ASSERT_FLOAT_EQ(bg.level.at(x, y), static_cast<float>(ref.mean)) << x << "," << y;
      ASSERT_FLOAT_EQ(bg.sigma.at(x, y), static_cast<float>(ref.sigma)) << x << "," << y;
    }
  }
}

TEST(Background, BiasAndNoiseMatchTruth) {
  const double sigma = 12.0;
  FrameCube cube = noisyCube(64, 48, 400, sigma, 5);
  NullProgress p;
  CancelToken c;
  const Background bg = estimateBackground(cube, {}, nullptr, p, c);
  double bias = 0.0;
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 64; ++x)
      bias += bg.level.at(x, y) - (500.0 + 0.5 * x + 0.25 * y);
  bias /= 64.0 * 48.0;
  EXPECT_LT(std::abs(bias), 0.05 * sigma);      // issue 3: bias < 0.05 sigma
  EXPECT_NEAR(bg.sigmaN, sigma, 0.03 * sigma);  // issue 3: sigma_n within 3%
  EXPECT_EQ(bg.pixelsFilled, 0u);
  subtractBackground(cube, bg.level, p, c);
  double mean = 0.0;
  for (float v : cube.pixels())
    mean += v;
  EXPECT_LT(std::abs(mean / static_cast<double>(cube.pixels().size())), 0.05 * sigma);
}

TEST(Background, ExcludedStaticSourceDoesNotBiasLevel) {
  // A static star (tracked telescope) is constant in every frame: without exclusion the per-pixel clip takes
  // it as background; with the star's MovingMask it is left out and the level falls back to the global mean.
  FrameCube cube = noisyCube(32, 32, 100, 5.0, 6);
  for (std::size_t n = 0; n < cube.frameCount(); ++n)
    cube.frame(n)[16 * 32 + 16] += 25.0f;  // below the strong-signal cut
  st::MovingMask mask(32, 32, cube.timeOffsetsS(), {});
  mask.set(16, 16);
  NullProgress p;
  CancelToken c;
  const Background with = estimateBackground(cube, {}, &mask, p, c);
  const Background without = estimateBackground(cube, {}, nullptr, p, c);
  EXPECT_NEAR(without.level.at(16, 16), 500.0 + 8.0 + 4.0 + 25.0, 2.0);
  EXPECT_NEAR(with.level.at(16, 16), with.global.mean, 1e-3);
  EXPECT_EQ(with.pixelsFilled, 1u);
}

TEST(Background, PixelBrightInEveryFrameIsItsOwnBackground) {
  // A static star's wing just outside its mask: 5 sigma above the sky in every frame. Its background is its
  // own mean (before 2026-11-27 the strong-signal cut at the global mean + 5 sigma took away the upper half of
  // its noise and left the level ~0.8 sigma low: a static residual of 11 sigma of a 200-frame mean).
  const double sigma = 5.0;
  FrameCube cube = noisyCube(32, 32, 200, sigma, 8);
  for (std::size_t n = 0; n < cube.frameCount(); ++n)
    for (int x = 10; x < 20; ++x)
      cube.frame(n)[16 * 32 + x] += static_cast<float>(5.0 * sigma);
  NullProgress p;
  CancelToken c;
  const Background bg = estimateBackground(cube, {}, nullptr, p, c);
  double meanBias = 0.0;
  for (int x = 10; x < 20; ++x) {
    double truthMean = 0.0;  // the pixel's own mean over the frames (its noise included, noisyCube's spot not)
    int frames = 0;
    for (std::size_t n = 0; n < cube.frameCount(); ++n) {
      if (static_cast<int>(n * 3) % 32 == x && static_cast<int>(n * 5) % 32 == 16) continue;
      truthMean += cube.frame(n)[16 * 32 + x];
      ++frames;
    }
    truthMean /= frames;
    meanBias += (bg.level.at(x, 16) - truthMean) / 10.0;
    EXPECT_NEAR(bg.level.at(x, 16), truthMean, 0.05 * sigma) << x;
    EXPECT_NEAR(bg.sigma.at(x, 16), sigma, 0.15 * sigma) << x;
  }
  EXPECT_LT(std::abs(meanBias), 0.02 * sigma);
}

TEST(Background, SourceOnAPixelInFewerThanHalfTheFramesIsStillCut) {
  // A slow mover on one pixel for 40% of the frames (consecutive), 20 sigma above the sky: the pixel's median
  // stays a background sample, the cut relative to it leaves the mover out, the level is the sky's.
  const double sigma = 5.0;
  FrameCube cube = noisyCube(32, 32, 200, sigma, 9);
  for (std::size_t n = 50; n < 130; ++n)
    cube.frame(n)[16 * 32 + 16] += static_cast<float>(20.0 * sigma);
  NullProgress p;
  CancelToken c;
  const Background bg = estimateBackground(cube, {}, nullptr, p, c);
  EXPECT_NEAR(bg.level.at(16, 16), 500.0 + 8.0 + 4.0, 1.5);  // 3.5 standard errors of 120 samples
  EXPECT_LT(bg.sigma.at(16, 16), 1.3 * sigma);
}

TEST(Background, AllMaskedThrowsClearError) {
  FrameCube cube(8, 8, 5);
  cube.info()[0].file = "all_masked.fits";
  cube.mask().assign(cube.pixels().size(), 1);
  NullProgress p;
  CancelToken c;
  try {
    estimateBackground(cube, {}, nullptr, p, c);
    FAIL() << "expected st::InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("masked"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("all_masked.fits"), std::string::npos);
  }
}

TEST(Background, SmoothNoiseMapIsFinite) {
  FrameCube cube = noisyCube(40, 30, 60, 7.0, 7);
  NullProgress p;
  CancelToken c;
  BackgroundParams params;
  params.noiseMap = true;
  params.noiseMapBoxPx = 9;
  const Background bg = estimateBackground(cube, params, nullptr, p, c);
  ASSERT_EQ(bg.noiseMap.size(), bg.sigma.size());
  for (float v : bg.noiseMap.pixels)
    EXPECT_NEAR(v, 7.0, 1.0);
}


// The strong-signal cut's lower medians by bisection over integer keys (AVX2) against gathering each column
// and nth_element (the path without AVX2): the same samples cut, bit for bit, on rows with NaN (left-out
// samples), negative values, +-0, exact ties (quantised counts), a column with no samples, one with one
// sample, bright sources on part of the frames, and widths that leave columns after the last 16.
TEST(Background, StrongSignalCutSimdEqualsSelection) {
  std::mt19937 rng(7);
  std::normal_distribution<float> g(0.0f, 1.0f);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (const auto& [nf, w] : std::vector<std::pair<std::size_t, int>>{{1, 16}, {2, 17}, {7, 33}, {60, 48},
                                                                       {201, 64}, {1500, 40}}) {
    for (int variant = 0; variant < 3; ++variant) {
      std::vector<float> buf(nf * static_cast<std::size_t>(w));
      for (std::size_t n = 0; n < nf; ++n)
        for (int x = 0; x < w; ++x) {
          float v = variant == 0 ? 5.0f * g(rng) : (variant == 1 ? std::round(3.0f * g(rng)) : 1e6f * g(rng));
          if (x % 5 == 1) v = -std::fabs(v) - 1000.0f;        // all negative
          if (x % 7 == 3 && u(rng) < 0.3f) v = 50.0f + 10.0f * u(rng);  // a source on ~30% of the frames
          if (x % 11 == 4) v = (n % 2) ? 0.0f : -0.0f;        // +-0 only
          if (u(rng) < 0.1f) v = std::nanf("");
          if (x == 2) v = std::nanf("");                    // no samples at all
          if (x == 9 && n > 0) v = std::nanf("");           // one sample
          buf[n * w + x] = v;
        }
      std::vector<float> a = buf, b = buf;
      std::vector<float> scratch;
      cutStrongAboveMedian(a.data(), nf, w, 2.5, scratch, true);
      cutStrongAboveMedian(b.data(), nf, w, 2.5, scratch, false);
      std::size_t cutA = 0, differ = 0;
      for (std::size_t i = 0; i < a.size(); ++i) {
        cutA += std::isnan(a[i]) && !std::isnan(buf[i]);
        differ += std::isnan(a[i]) != std::isnan(b[i]) || (!std::isnan(a[i]) && a[i] != b[i]);
      }
      EXPECT_EQ(differ, 0u) << nf << " frames x " << w << ", variant " << variant;
      if (nf >= 60) {
        EXPECT_GT(cutA, 0u) << "the rows have sources to cut";
      }
    }
  }
}

}  // namespace
}  // namespace st::stats

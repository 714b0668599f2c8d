// The noise model for real frames and the inverse-variance-weighted matched filter (stats/noise_model.hpp,
// stack/matched_filter.hpp). Oracles: the paper's uniform filter (identity for uniform noise), the likelihood
// statistic sum psi / sqrt(sum phi) computed directly (Whidden et al. 2019), known simulated noise levels.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "st/common/frame_cube.hpp"
#include "st/stack/matched_filter.hpp"
#include "st/stats/background.hpp"
#include "st/stats/noise_model.hpp"
#include "test_support.hpp"

namespace st::stats {
namespace {

FrameCube noiseCube(int w, int h, std::size_t nf, unsigned seed, double sigma) {
  FrameCube cube(w, h, nf);
  std::mt19937 rng(seed);
  std::normal_distribution<float> g(0.0f, static_cast<float>(sigma));
  for (auto& v : cube.pixels())
    v = g(rng);
  for (std::size_t n = 0; n < nf; ++n) {
    cube.info()[n].mjdMid = 60000.0 + n * 300.0 / 86400.0;
    cube.info()[n].exposureS = 300.0;
  }
  return cube;
}

double robustSigma(std::vector<float> v) {
  auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  const float med = *mid;
  for (auto& x : v)
    x = std::fabs(x - med);
  std::nth_element(v.begin(), mid, v.end());
  return 1.4826 * *mid;
}

TEST(WeightedFilter, UniformNoiseIsThePapersFilter) {
  FrameCube a = noiseCube(96, 80, 6, 1, 5.0);
  FrameCube b = a;
  const stack::FilterKernel k = stack::makeFilterKernel(psf::Moffat::fromFwhm(3.0, 4.0));
  NullProgress p;
  CancelToken c;
  const NoiseModel uniform = NoiseModel::uniform(96, 80, 6, 5.0);
  const auto ra = stack::filterCube(a, k, p, c);
  const auto rb = stack::filterCube(b, k, p, c, &uniform);
  EXPECT_NEAR(rb.sigmaF, ra.sigmaF, 1e-4 * ra.sigmaF);
  double worst = 0.0;
  for (std::size_t n = 0; n < 6; ++n)
    for (int y = k.halfSize; y < 80 - k.halfSize; ++y)
      for (int x = k.halfSize; x < 96 - k.halfSize; ++x) {
        const std::size_t i = n * a.framePixels() + std::size_t(y) * 96 + x;
        worst = std::max(worst, std::fabs(double(a.pixels()[i]) - b.pixels()[i]));
      }
  EXPECT_LT(worst, 1e-4 * ra.sigmaF);
}

// Noise that doubles across the frame (vignetting) and differs between frames (sky): after the weighted
// filter every part of every frame has the same noise, and a static source's stacked statistic equals the
// likelihood statistic computed from psi and phi directly.
TEST(WeightedFilter, VaryingNoiseIsNormalisedAndGivesTheLikelihoodStatistic) {
  const int w = 256, h = 160;
  const std::size_t nf = 12;
  FrameCube cube = noiseCube(w, h, nf, 2, 1.0);
  NoiseModel m;
  m.variance = Image(w, h);
  m.frameScale.resize(nf);
  for (std::size_t n = 0; n < nf; ++n)
    m.frameScale[n] = 1.0 + 0.5 * (n % 3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const double s = 4.0 * (1.0 + double(x) / (w - 1));  // 4 .. 8 counts
      m.variance.at(x, y) = static_cast<float>(s * s);
    }
  m.sigmaRef = 6.0;
  const psf::Moffat psf = psf::Moffat::fromFwhm(3.0, 4.0);
  const stack::FilterKernel k = stack::makeFilterKernel(psf);
  const int sx = 200, sy = 80;  // a static source in the noisy half
  const double alpha = 6.0;     // peak counts per frame
  for (std::size_t n = 0; n < nf; ++n) {
    float* f = cube.frame(n);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const std::size_t i = std::size_t(y) * w + x;
        f[i] = static_cast<float>(f[i] * std::sqrt(m.variance.pixels[i]) * m.frameScale[n]);
        if (std::abs(x - sx) <= k.halfSize && std::abs(y - sy) <= k.halfSize)
          f[i] += static_cast<float>(alpha * k.kernel.at(x - sx + k.halfSize, y - sy + k.halfSize));
      }
  }
  // The likelihood statistic at the source, directly.
  double psi = 0.0, phi = 0.0;
  for (std::size_t n = 0; n < nf; ++n) {
    const double s2 = m.frameScale[n] * m.frameScale[n];
    for (int dy = -k.halfSize; dy <= k.halfSize; ++dy)
      for (int dx = -k.halfSize; dx <= k.halfSize; ++dx) {
        const double kv = k.kernel.at(dx + k.halfSize, dy + k.halfSize);
        const double var = m.variance.at(sx + dx, sy + dy) * s2;
        psi += kv * cube.frame(n)[std::size_t(sy + dy) * w + sx + dx] / var;
        phi += kv * kv / var;
      }
  }
  const double likelihood = psi / std::sqrt(phi);
  NullProgress p;
  CancelToken c;
  const auto r = stack::filterCube(cube, k, p, c, &m);
  double sum = 0.0;
  for (std::size_t n = 0; n < nf; ++n)
    sum += cube.frame(n)[std::size_t(sy) * w + sx];
  const double stacked = sum / (r.sigmaF * std::sqrt(double(nf)));
  // sigma_F is measured (robust) where the exact statistic uses the model: agree within the estimate's ~2%.
  EXPECT_NEAR(stacked, likelihood, 0.03 * std::fabs(likelihood)) << "sigma_F " << r.sigmaF;
  // Same noise on the quiet and the noisy side, in the frames of every scale (pooled over the 4 frames of
  // each scale: the filtered noise is correlated over ~30 px, so one frame's half has ~600 independent
  // values).
  for (std::size_t scale = 0; scale < 3; ++scale) {
    std::vector<float> left, right;
    for (std::size_t n = scale; n < nf; n += 3)
      for (int y = 10; y < h - 10; ++y)
        for (int x = 10; x < w - 10; ++x) {
          if (std::hypot(x - sx, y - sy) < 12) continue;
          (x < w / 2 ? left : right).push_back(cube.frame(n)[std::size_t(y) * w + x]);
        }
    EXPECT_NEAR(robustSigma(left), robustSigma(right), 0.06 * robustSigma(right)) << "frame scale " << scale;
  }
}

TEST(NoiseModel, RecoversFrameScalesAndTheVarianceMap) {
  const int w = 120, h = 100;
  const std::size_t nf = 30;
  FrameCube cube = noiseCube(w, h, nf, 3, 1.0);
  Image sigma(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      sigma.at(x, y) = static_cast<float>(10.0 + 10.0 * y / (h - 1));
  for (std::size_t n = 0; n < nf; ++n)
    for (std::size_t i = 0; i < cube.framePixels(); ++i)
      cube.frame(n)[i] *= sigma.pixels[i] * (n == 5 ? 2.0f : 1.0f);
  CancelToken c;
  const NoiseModel m = estimateNoiseModel(cube, sigma, {}, {}, c);
  EXPECT_NEAR(m.frameScale[5], 2.0, 0.1);
  EXPECT_NEAR(m.frameScale[0], 1.0, 0.05);
  EXPECT_NEAR(std::sqrt(m.variance.at(60, 10)), sigma.at(60, 10), 0.05 * sigma.at(60, 10));
  EXPECT_NEAR(std::sqrt(m.variance.at(60, 90)), sigma.at(60, 90), 0.05 * sigma.at(60, 90));
}

TEST(NoiseModel, ResidualMeansAreRemovedAndZerosKept) {
  FrameCube cube = noiseCube(256, 192, 4, 4, 1.0);
  for (std::size_t n = 0; n < 4; ++n)
    for (int y = 0; y < 192; ++y)
      for (int x = 0; x < 256; ++x) {
        float& v = cube.frame(n)[std::size_t(y) * 256 + x];
        v += static_cast<float>(0.2 + 0.002 * x - 0.001 * y);  // a residual offset and gradient, in sigma
        if (x > 100 && x < 120) v = 0.0f;                      // a masked stripe
      }
  NullProgress p;
  CancelToken c;
  const double rms = removeResidualMeans(cube, 64, 5.0, p, c);
  EXPECT_GT(rms, 0.1);
  double s = 0.0;
  std::size_t count = 0;
  for (std::size_t n = 0; n < 4; ++n)
    for (int y = 0; y < 192; ++y)
      for (int x = 0; x < 256; ++x) {
        const float v = cube.frame(n)[std::size_t(y) * 256 + x];
        if (x > 100 && x < 120) {
          ASSERT_EQ(v, 0.0f);
          continue;
        }
        s += v;
        ++count;
      }
  EXPECT_NEAR(s / count, 0.0, 0.01);
}

TEST(NoiseModel, FrameBackgroundsRemoveOffsetsAndGradients) {
  FrameCube cube = noiseCube(256, 256, 6, 5, 10.0);
  for (std::size_t n = 0; n < 6; ++n)
    for (int y = 0; y < 256; ++y)
      for (int x = 0; x < 256; ++x)
        cube.frame(n)[std::size_t(y) * 256 + x] +=
            static_cast<float>(1000.0 + 100.0 * n - 80.0 * (n % 2) + 0.3 * n * x);
  NullProgress p;
  CancelToken c;
  const FrameBackgrounds b = removeFrameBackgrounds(cube, {}, p, c);
  ASSERT_EQ(b.framesSkipped, 0u);
  // Per pixel, the frame-to-frame scatter is the noise again (it was dominated by offsets of ~100s).
  std::vector<float> sd;
  for (std::size_t i = 0; i < cube.framePixels(); i += 97) {
    double s = 0, ss = 0;
    for (std::size_t n = 0; n < 6; ++n) {
      s += cube.frame(n)[i];
      ss += double(cube.frame(n)[i]) * cube.frame(n)[i];
    }
    sd.push_back(static_cast<float>(std::sqrt(std::max(0.0, (ss - s * s / 6) / 5))));
  }
  std::sort(sd.begin(), sd.end());
  EXPECT_NEAR(sd[sd.size() / 2], 10.0 * 0.95, 1.5);  // median of a chi with 5 dof, sigma 10
}

// A slow mover: 1.2 px per frame, FWHM 2.4 px, 15 frames. The paper's per-pixel mean takes ~2/15 of its flux
// into the background; leaving out the frames near each frame keeps it.
TEST(PixelBackground, SlowMoverKeepsItsFlux) {
  const int w = 80, h = 40;
  const std::size_t nf = 15;
  auto make = [&] {
    FrameCube cube = noiseCube(w, h, nf, 6, 0.01);
    for (auto& v : cube.pixels())
      v += 100.0f;
    const psf::Moffat psf = psf::Moffat::fromFwhm(2.4, 3.0);
    for (std::size_t n = 0; n < nf; ++n)
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
          cube.frame(n)[std::size_t(y) * w + x] +=
              static_cast<float>(3.0 * psf(x - (30.0 + 1.2 * n), y - 20.0));
    return cube;
  };
  // Along the track: an aperture of 3 px radius about the mover in each frame.
  auto flux = [&](const FrameCube& cube) {
    double s = 0;
    for (std::size_t n = 0; n < nf; ++n)
      for (int y = 10; y < 30; ++y)
        for (int x = 20; x < 60; ++x)
          if (std::hypot(x - (30.0 + 1.2 * n), y - 20.0) <= 3.0) s += cube.frame(n)[std::size_t(y) * w + x];
    return s;
  };
  FrameCube truth = make();
  for (auto& v : truth.pixels())
    v -= 100.0f;
  const double total = flux(truth);
  NullProgress p;
  CancelToken c;
  BackgroundParams paper;
  paper.moverWindowFraction = 0.0;
  paper.minSamples = 3;
  paper.strongSignalXi = 1e9;  // a faint mover: no sample is a "strong signal"
  FrameCube a = make();
  (void)subtractPixelBackground(a, paper, nullptr, p, c);
  BackgroundParams keep = paper;
  keep.moverWindowFraction = 0.25;
  FrameCube b = make();
  (void)subtractPixelBackground(b, keep, nullptr, p, c);
  std::printf("total %g paper %g window %g\n", total, flux(a), flux(b));
  EXPECT_LT(flux(a) / total, 0.93);
  EXPECT_GT(flux(b) / total, 0.97);
}

// How slow is too slow (issue 14: slow movers keep >= 95% of their flux): the same 15 frames, a mover of
// FWHM 2.4 px crossing 1 to 8 FWHM over the span, background with the default window (frames within
// +-span/4 left out). Flux kept within 3 px of the track against the truth, mean of 4 noise seeds. The
// frames just outside the window see the mover (span/4) x v away: 2 FWHM over the span leaves it within
// half a FWHM there, and the background takes a share of its light. Measured 2026-11-26 (dev VM): 1 FWHM
// over the span 0.087 of the flux kept, 2: 0.366, 3: 0.657, 4: 0.831, 6: 0.955, 8: 0.978. So >= 95% from
// 6 FWHM over the span, with the default window; slower movers lose flux to their own background (README).
TEST(PixelBackground, FluxKeptAgainstTheMoversSpeed) {
  const int w = 120, h = 40;
  const std::size_t nf = 15;
  const double fwhm = 2.4;
  const psf::Moffat psf = psf::Moffat::fromFwhm(fwhm, 3.0);
  NullProgress p;
  CancelToken c;
  BackgroundParams params;
  params.minSamples = 3;
  params.strongSignalXi = 1e9;
  std::printf("FWHM over the span | flux kept\n");
  for (const double fwhms : {1.0, 2.0, 3.0, 4.0, 6.0, 8.0}) {
    const double perFrame = fwhms * fwhm / (nf - 1);
    double kept = 0.0, total = 0.0;
    for (std::uint32_t seed = 0; seed < 4; ++seed) {
      FrameCube cube = noiseCube(w, h, nf, 100 + seed, 0.3);
      FrameCube truth(w, h, nf);
      for (std::size_t n = 0; n < nf; ++n)
        for (int y = 0; y < h; ++y)
          for (int x = 0; x < w; ++x) {
            const auto v = static_cast<float>(3.0 * psf(x - (40.0 + perFrame * n), y - 20.0));
            cube.frame(n)[std::size_t(y) * w + x] += 100.0f + v;
            truth.frame(n)[std::size_t(y) * w + x] = v;
          }
      (void)subtractPixelBackground(cube, params, nullptr, p, c);
      for (std::size_t n = 0; n < nf; ++n)
        for (int y = 14; y < 27; ++y)
          for (int x = 30; x < 100; ++x)
            if (std::hypot(x - (40.0 + perFrame * n), y - 20.0) <= 3.0) {
              kept += cube.frame(n)[std::size_t(y) * w + x];
              total += truth.frame(n)[std::size_t(y) * w + x];
            }
    }
    std::printf("%18.0f | %.3f\n", fwhms, kept / total);
    if (fwhms >= 6.0) {
      EXPECT_GT(kept / total, 0.95) << fwhms << " FWHM over the span";
    }
    if (fwhms >= 4.0) {
      EXPECT_GT(kept / total, 0.8) << fwhms << " FWHM over the span";
    }
    if (fwhms <= 1.0) {
      EXPECT_LT(kept / total, 0.9) << "a static-looking mover is absorbed (the oracle)";
    }
  }
}

}  // namespace
}  // namespace st::stats

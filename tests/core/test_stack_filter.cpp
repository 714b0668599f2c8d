// Matched filter: kernel, peak response, filtered-noise measurement.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "st/common/error.hpp"
#include "st/common/frame_cube.hpp"
#include "st/psf/moffat.hpp"
#include "st/stack/matched_filter.hpp"

namespace st::stack {
namespace {

FrameCube noiseCube(int w, int h, std::size_t n, float sigma, unsigned seed) {
  FrameCube cube(w, h, n);
  std::mt19937 rng(seed);
  std::normal_distribution<float> g(0.0f, sigma);
  for (auto& p : cube.pixels())
    p = g(rng);
  for (std::size_t i = 0; i < n; ++i)
    cube.info()[i].mjdMid = 60000.0 + double(i) / 86400.0;
  return cube;
}

TEST(FilterKernel, TruncatedAtOneThousandthOfPeak) {
  const psf::Moffat m{3.3, 4.0};
  const FilterKernel k = makeFilterKernel(m);
  EXPECT_EQ(k.halfSize, 7);  // R sqrt(1000^(1/4) - 1) = 7.10 px
  EXPECT_EQ(k.kernel.width, 15);
  EXPECT_NEAR(k.kernel.at(7, 7), m.pixelMean(0, 0), 1e-7);
  EXPECT_FLOAT_EQ(k.kernel.at(0, 0), 0.0f);  // corner at r = 9.9 px, beyond the truncation disc
  // What the truncation loses: the untruncated sum of K^2 (over +-60 px) is at most 0.3% larger.
  double full = 0.0;
  for (int y = -60; y <= 60; ++y)
    for (int x = -60; x <= 60; ++x)
      full += std::pow(m.pixelMean(x, y), 2);
  EXPECT_LT(k.sumSquares, full);
  EXPECT_GT(k.sumSquares, 0.997 * full);
  // ... and the pixel mean of P sums to ~ the integral of P, pi R^2 / (beta - 1), less the truncated tail.
  EXPECT_NEAR(k.sum, m.integral(), 0.03 * m.integral());
  EXPECT_THROW((void)makeFilterKernel(psf::Moffat{0.0, 4.0}), InputError);
  EXPECT_THROW((void)makeFilterKernel(m, 0.0), InputError);
}

// sigma_F of filtered white noise is sigma sqrt(sum K^2) (2% tolerance; 64 frames x ~1.4e4 samples each
// give a MAD-estimate precision of ~0.2%, correlations between samples 3 px apart leave it well inside).
TEST(MatchedFilter, FilteredWhiteNoiseSigmaMatchesPrediction) {
  FrameCube cube = noiseCube(128, 128, 70, 5.0f, 11);
  const FilterKernel k = makeFilterKernel(psf::Moffat::fromFwhm(3.0));
  NullProgress progress;
  CancelToken cancel;
  const MatchedFilterResult r = filterCube(cube, k, progress, cancel);
  const double predicted = 5.0 * std::sqrt(k.sumSquares);
  EXPECT_NEAR(r.sigmaF, predicted, 0.02 * predicted);
  EXPECT_GT(r.noiseSamples, 50000u);
  EXPECT_NEAR(measureFilteredNoise(cube, k.halfSize), predicted, 0.02 * predicted);
}

// Zeroed regions (static sources) must not bias sigma_F low: their neighbourhood is excluded.
TEST(MatchedFilter, ZeroedRegionsDoNotBiasSigmaF) {
  FrameCube cube = noiseCube(128, 128, 40, 2.0f, 12);
  for (std::size_t n = 0; n < cube.frameCount(); ++n)
    for (int y = 0; y < 128; ++y)
      for (int x = 0; x < 128; ++x)
        if ((x / 16 + y / 16) % 3 == 0) cube.frame(n)[y * 128 + x] = 0.0f;
  const FilterKernel k = makeFilterKernel(psf::Moffat::fromFwhm(2.5));
  NullProgress progress;
  CancelToken cancel;
  const MatchedFilterResult r = filterCube(cube, k, progress, cancel);
  const double predicted = 2.0 * std::sqrt(k.sumSquares);
  EXPECT_NEAR(r.sigmaF, predicted, 0.03 * predicted);
}

// A PSF-shaped source alpha K filters to alpha sum K^2 at its centre (float precision).
TEST(MatchedFilter, PeakResponseToPsfShapedSource) {
  const psf::Moffat m{2.2, 3.0};
  const FilterKernel k = makeFilterKernel(m);
  FrameCube cube(64, 64, 1);
  const double alpha = 250.0;
  for (int y = 0; y < 64; ++y)
    for (int x = 0; x < 64; ++x)
      cube.frame(0)[y * 64 + x] = float(alpha * m.pixelMean(x - 30, y - 33));
  filterFrame(cube.frame(0), 64, 64, k);
  const float* f = cube.frame(0);
  // Only the kernel's support enters, where the source equals alpha K exactly.
  EXPECT_NEAR(f[33 * 64 + 30], alpha * k.sumSquares, 1e-5 * alpha * k.sumSquares);
  for (int y = 0; y < 64; ++y)
    for (int x = 0; x < 64; ++x)
      EXPECT_LE(f[y * 64 + x], f[33 * 64 + 30]);
}

// Oracle for the FFT convolution: the direct correlation sum, with 0 outside the frame, on an odd-sized
// frame with sources at the edges and a kernel made asymmetric (so a mirrored or shifted kernel would
// show). Tolerance 2e-6 of the largest |value|: float rounding of the FFT's sums.
TEST(MatchedFilter, FftFilterEqualsTheDirectSumWithZerosOutside) {
  const int w = 71, h = 53;
  FilterKernel k = makeFilterKernel(psf::Moffat::fromFwhm(3.0));
  k.kernel.at(k.halfSize + 2, k.halfSize - 1) += 0.3f;
  k.kernel.at(0, k.halfSize) += 0.2f;
  FrameCube cube = noiseCube(w, h, 1, 5.0f, 9);
  float* f = cube.frame(0);
  f[0] += 500.0f;
  f[(h - 1) * w + (w - 2)] += 300.0f;
  f[20 * w + 35] = 0.0f;
  const std::vector<float> in(f, f + std::size_t(w) * h);
  filterFrame(f, w, h, k);
  const int half = k.halfSize;
  double maxAbs = 0.0, maxDiff = 0.0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      double direct = 0.0;
      for (int ky = 0; ky < k.kernel.height; ++ky)
        for (int kx = 0; kx < k.kernel.width; ++kx) {
          const int sx = x + kx - half, sy = y + ky - half;
          if (sx >= 0 && sy >= 0 && sx < w && sy < h) direct += double(k.kernel.at(kx, ky)) * in[sy * w + sx];
        }
      maxAbs = std::max(maxAbs, std::fabs(direct));
      maxDiff = std::max(maxDiff, std::fabs(direct - f[y * w + x]));
    }
  EXPECT_LT(maxDiff, 2e-6 * maxAbs) << "max |FFT - direct| " << maxDiff << " of max |value| " << maxAbs;
  // filterCube gives every frame what filterFrame gives it.
  FrameCube two = noiseCube(131, 97, 2, 5.0f, 10);  // large enough for filterCube's sigma_F
  FrameCube byFrame = two;
  NullProgress progress;
  CancelToken cancel;
  filterCube(two, k, progress, cancel);
  for (std::size_t n = 0; n < 2; ++n) {
    filterFrame(byFrame.frame(n), 131, 97, k);
    for (std::size_t i = 0; i < byFrame.framePixels(); ++i)
      ASSERT_NEAR(two.frame(n)[i], byFrame.frame(n)[i], 1e-5f) << "frame " << n << " pixel " << i;
  }
}

TEST(MatchedFilter, MakesTheSearchInput) {
  FrameCube cube = noiseCube(96, 96, 20, 3.0f, 21);
  const psf::Moffat m = psf::Moffat::fromFwhm(3.2);
  NullProgress progress;
  CancelToken cancel;
  const search::FilteredCube fc = makeFilteredCube(std::move(cube), m, Velocity{0.5, 0.0}, progress, cancel);
  const double predicted = 3.0 * std::sqrt(makeFilterKernel(m).sumSquares);
  EXPECT_NEAR(fc.sigmaF, predicted, 0.03 * predicted);
  EXPECT_DOUBLE_EQ(fc.psfFwhmPx, m.fwhm());
  EXPECT_EQ(fc.skyRate, (Velocity{0.5, 0.0}));
  EXPECT_EQ(fc.frames.frameCount(), 20u);
}

TEST(MatchedFilter, CancelsAndRejectsAllMasked) {
  FrameCube cube = noiseCube(64, 64, 8, 1.0f, 3);
  const FilterKernel k = makeFilterKernel(psf::Moffat::fromFwhm(3.0));
  NullProgress progress;
  CancelToken cancel;
  cancel.cancel();
  EXPECT_THROW((void)filterCube(cube, k, progress, cancel), Cancelled);
  cancel.reset();
  cube.mask().assign(cube.pixels().size(), 1);
  EXPECT_THROW((void)filterCube(cube, k, progress, cancel), InputError);
  for (float p : cube.pixels())
    ASSERT_EQ(p, 0.0f);  // masked pixels were zeroed, no NaN flowing on
}

}  // namespace
}  // namespace st::stack

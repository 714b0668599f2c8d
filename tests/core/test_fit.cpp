// Co-moving PSF fit (paper \label{comoving_lsq}) and the paper's precision formulas.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "st/common/error.hpp"
#include "st/fit/comoving_fit.hpp"
#include "st/fit/montecarlo.hpp"
#include "st/fit/pixel_psf.hpp"
#include "st/fit/uncertainty.hpp"

namespace st::fit {
namespace {

const psf::Moffat kPaperPsf{3.3, 4.0};

TEST(PixelPsf, GradientMatchesFiniteDifferences) {
  for (const auto& [u, v] : {std::pair{0.3, -0.7}, {2.1, 1.4}, {-4.0, 0.2}, {0.0, 0.0}}) {
    const PsfSample s = pixelPsf(kPaperPsf, u, v);
    const double h = 1e-5;
    const double du = (pixelPsfValue(kPaperPsf, u + h, v) - pixelPsfValue(kPaperPsf, u - h, v)) / (2 * h);
    const double dv = (pixelPsfValue(kPaperPsf, u, v + h) - pixelPsfValue(kPaperPsf, u, v - h)) / (2 * h);
    EXPECT_NEAR(s.du, du, 1e-8);
    EXPECT_NEAR(s.dv, dv, 1e-8);
    EXPECT_NEAR(s.value, pixelPsfValue(kPaperPsf, u, v), 1e-14);
  }
}

TEST(PixelPsf, IntegratesToTheMoffatIntegral) {
  // Pixel integration preserves the total: sum over pixels = pi R^2 / (beta - 1) (to the 3x3 rule's error).
  double sum = 0.0;
  for (int y = -60; y <= 60; ++y) {
    for (int x = -60; x <= 60; ++x)
      sum += pixelPsfValue(kPaperPsf, x + 0.37, y - 0.21);
  }
  EXPECT_NEAR(sum / kPaperPsf.integral(), 1.0, 1e-4);
  // The pixel-integrated peak is within 0.7% of a fine (51x51) pixel integral.
  double fine = 0.0;
  for (int j = 0; j < 51; ++j) {
    for (int i = 0; i < 51; ++i)
      fine += kPaperPsf((i + 0.5) / 51 - 0.5, (j + 0.5) / 51 - 0.5);
  }
  fine /= 51.0 * 51.0;
  EXPECT_NEAR(pixelPsfValue(kPaperPsf, 0, 0) / fine, 1.0, 7e-3);
  // Sum of squares: below the continuous integral of P^2 (pixel smoothing), by a few percent for W ~ 2.9.
  const double s2 = pixelPsfSumOfSquares(kPaperPsf);
  EXPECT_LT(s2, kPaperPsf.integralOfSquare());
  EXPECT_GT(s2, 0.95 * kPaperPsf.integralOfSquare());
}

TEST(PaperFormulas, ExactValues) {
  // detection_snr: alpha sqrt(N_f) sqrt(sum P^2) / sigma_n
  EXPECT_DOUBLE_EQ(detectionSnr(2.0, 100.0, 4.0, 5.0), 2.0 * 10.0 * 2.0 / 5.0);
  EXPECT_DOUBLE_EQ(detectionSnrApprox(100.0, 16.0, 2.0, 3.0), 0.6 * 100.0 * 4.0 / 6.0);
  // eq:sig with N_ph = 100, W = 3, sigma_n = 2, N_f = 25
  const double expected = std::sqrt(0.457 / 100.0 + 1.37 * 4.0 * 9.0 / 1e4) * 3.0 / 5.0;
  EXPECT_DOUBLE_EQ(positionSigmaPaper(100.0, 3.0, 2.0, 25.0), expected);
  EXPECT_DOUBLE_EQ(positionSigmaFromSnr(3.0, 15.0), 0.65 * 3.0 / 15.0);
  EXPECT_DOUBLE_EQ(velocitySigma(0.1, 30.0), std::sqrt(12.0) * 0.1 / 30.0);
}

TEST(PaperFormulas, EffectiveDurationOfEvenFramesIsTheirCoverage) {
  std::vector<double> t;
  for (int n = 0; n < 500; ++n)
    t.push_back(0.06 * n - 7.0);
  EXPECT_NEAR(effectiveDurationS(t), 0.06 * std::sqrt(500.0 * 500.0 - 1.0), 1e-9);
  EXPECT_NEAR(effectiveDurationS(t) / (500 * 0.06), 1.0, 1e-5);
  EXPECT_EQ(effectiveDurationS({1.0}), 0.0);
}

TEST(PaperFormulas, AreMutuallyConsistentForThePaperPsf) {
  // The paper's approximations agree with the exact forms for R = 3.3, beta = 4 to ~10% (the SNR one is
  // 10.1% high against the pixel-integrated sum P^2; its 0.6 is a rounded coefficient).
  const double w = kPaperPsf.fwhm();
  const double nph = 200.0, nf = 500.0, sn = 5.0;
  const double alpha = nph / kPaperPsf.integral();
  const double snr = detectionSnr(alpha, nf, pixelPsfSumOfSquares(kPaperPsf), sn);
  EXPECT_NEAR(detectionSnrApprox(nph, nf, sn, w) / snr, 1.0, 0.12);
  // Background-limited eq:sig vs cent_snr.
  const double bgOnly = std::sqrt(1.37) * sn * w * w / (nph * std::sqrt(nf));
  EXPECT_NEAR(positionSigmaFromSnr(w, snr) / bgOnly, 1.0, 0.10);
}

// A cube of a moving source, optionally noisy.
FrameCube movingCube(const MovingSource& src, int frames, double sigmaN, std::uint64_t seed, int size = 48) {
  FrameCube cube = makeEmptyCube(size, frames, 0.06);
  renderMovingSource(cube, kPaperPsf, src);
  if (sigmaN > 0) addNoise(cube, sigmaN, true, seed);
  return cube;
}

FitOptions paperOptions() {
  FitOptions o;
  o.psf = kPaperPsf;
  return o;
}

TEST(ComovingFit, RecoversANoiseFreeSourceFromAnOffsetStart) {
  const MovingSource src{23.3, 25.8, {3.0, -1.5}, 2000.0};
  const FrameCube cube = movingCube(src, 40, 0.0, 0);
  FitParams start;
  start.xc = 24;
  start.yc = 25;
  start.v = {2.5, -1.0};
  start.alpha = std::nan("");
  std::vector<double> costs;
  const FitResult r = fitComoving(
      cube, start, paperOptions(), [&](const FitIteration& it) { costs.push_back(it.cost); },
      *std::make_unique<CancelToken>());
  ASSERT_TRUE(r.ok()) << r.message;
  // 5x5 rendering vs 3x3 model: agreement to a few thousandths of a pixel.
  EXPECT_NEAR(r.params.xc, src.x, 2e-3);
  EXPECT_NEAR(r.params.yc, src.y, 2e-3);
  EXPECT_NEAR(r.params.v.vx, src.v.vx, 2e-3);
  EXPECT_NEAR(r.params.v.vy, src.v.vy, 2e-3);
  EXPECT_NEAR(r.photonsPerFrame / src.photons, 1.0, 3e-3);
  EXPECT_NEAR(r.params.i0, 0.0, 1e-2);
  // The callback saw every iteration, the cost never rose and fell by orders of magnitude.
  ASSERT_EQ(costs.size(), r.costHistory.size());
  ASSERT_EQ(static_cast<int>(costs.size()), r.iterations + 1);
  for (std::size_t i = 1; i < costs.size(); ++i)
    EXPECT_LE(costs[i], costs[i - 1]);
  EXPECT_LT(costs.back(), 1e-3 * costs.front());
  // Residual image: data - model is tiny against the stacked signal.
  float peak = 0.0f, worst = 0.0f;
  for (std::size_t i = 0; i < r.dataStack.size(); ++i) {
    peak = std::max(peak, r.dataStack.pixels[i]);
    worst = std::max(worst, std::abs(r.residualStack.pixels[i]));
  }
  EXPECT_GT(peak, 0.0f);
  EXPECT_LT(worst, 5e-3f * peak);
}

TEST(ComovingFit, UsesRealFrameTimesForUnevenCadence) {
  const MovingSource src{22.6, 24.1, {4.0, 2.0}, 3000.0};
  FrameCube cube = makeEmptyCube(48, 30, 0.06);
  for (std::size_t n = 0; n < cube.frameCount(); ++n) {
    // gaps: frames 10-19 taken 1 s later
    cube.info()[n].mjdMid = 60000.0 + (0.06 * n + (n >= 10 ? 1.0 : 0.0) + (n >= 20 ? 0.5 : 0.0)) / 86400.0;
  }
  renderMovingSource(cube, kPaperPsf, src);
  FitParams start{{3.5, 2.3}, 23.0, 24.0, std::nan(""), 0.0};
  const FitResult r = fitComoving(cube, start, paperOptions());
  ASSERT_TRUE(r.ok()) << r.message;
  EXPECT_NEAR(r.params.v.vx, 4.0, 2e-3);
  EXPECT_NEAR(r.params.v.vy, 2.0, 2e-3);
  EXPECT_NEAR(r.params.xc, src.x, 2e-3);
}

TEST(ComovingFit, HessianErrorsMatchThePaperFormulaAndTheSpreadIsHonest) {
  const MovingSource src{24.2, 23.7, {2.0, 1.0}, 300.0};
  const FrameCube cube = movingCube(src, 50, 3.0, 42);
  FitOptions o = paperOptions();
  o.sigmaN = 3.0;
  const FitResult r = fitComoving(cube, {{2.1, 0.9}, 24.0, 24.0, std::nan(""), 0.0}, o);
  ASSERT_TRUE(r.ok()) << r.message;
  // Photon and background terms of eq:sig are comparable here: the noise-model (sandwich) errors carry
  // both; the plain Hessian errors (one variance for all pixels) carry less than eq:sig.
  EXPECT_NEAR(r.sigmaNoiseModel[kXc] / r.sigmaPosPaper, 1.0, 0.10);
  EXPECT_NEAR(r.sigmaNoiseModel[kVx] / r.sigmaVelPaper, 1.0, 0.10);
  EXPECT_LT(r.sigma[kXc], r.sigmaNoiseModel[kXc]);
  EXPECT_GT(r.sigma[kXc], 0.5 * r.sigmaNoiseModel[kXc]);
  EXPECT_NEAR(r.reducedChi2, 1.0, 0.1);
  EXPECT_LT(std::abs(r.params.xc - src.x), 5 * r.sigma[kXc]);
  EXPECT_NEAR(r.snr, detectionSnr(src.photons / kPaperPsf.integral(), 50, r.sumP2, 3.0), 5.0);
}

// The EM register's excess noise doubles the source's photon-noise variance in the noise-model covariance:
// the same fit, the same parameters, larger noise-model errors (by the photon term's share; here, where the
// photon and background terms are comparable, by 10-40%); the Hessian errors and eq:sig are unchanged.
TEST(ComovingFit, ExcessNoiseWidensOnlyTheNoiseModelErrors) {
  const MovingSource src{24.2, 23.7, {2.0, 1.0}, 300.0};
  const FrameCube cube = movingCube(src, 50, 3.0, 42);
  FitOptions o = paperOptions();
  o.sigmaN = 3.0;
  const FitResult plain = fitComoving(cube, {{2.1, 0.9}, 24.0, 24.0, std::nan(""), 0.0}, o);
  o.excessNoise = 2.0;
  const FitResult em = fitComoving(cube, {{2.1, 0.9}, 24.0, 24.0, std::nan(""), 0.0}, o);
  ASSERT_TRUE(plain.ok() && em.ok());
  EXPECT_EQ(em.params.xc, plain.params.xc);
  EXPECT_EQ(em.sigma[kXc], plain.sigma[kXc]);
  EXPECT_EQ(em.sigmaPosPaper, plain.sigmaPosPaper);
  const double ratio = em.sigmaNoiseModel[kXc] / plain.sigmaNoiseModel[kXc];
  EXPECT_GT(ratio, 1.1);
  EXPECT_LT(ratio, std::sqrt(2.0));  // the background's share stays as it was
}

TEST(ComovingFit, FixedVelocityStaysFixed) {
  const MovingSource src{24.4, 23.6, {0.0, 0.0}, 1000.0};
  const FrameCube cube = movingCube(src, 20, 1.0, 7);
  FitOptions o = paperOptions();
  o.fixVelocity = true;
  const FitResult r = fitComoving(cube, {{0.0, 0.0}, 24.0, 24.0, std::nan(""), 0.0}, o);
  ASSERT_TRUE(r.ok()) << r.message;
  EXPECT_EQ(r.params.v.vx, 0.0);
  EXPECT_EQ(r.params.v.vy, 0.0);
  EXPECT_EQ(r.sigma[kVx], 0.0);
  EXPECT_EQ(r.freeParams, 4);
  EXPECT_NEAR(r.params.xc, src.x, 0.05);
}

TEST(ComovingFit, MaskedPixelsAreIgnored) {
  const MovingSource src{24.4, 23.6, {1.0, 0.0}, 1000.0};
  FrameCube cube = movingCube(src, 20, 0.0, 0);
  cube.mask().assign(cube.pixels().size(), 0);
  for (std::size_t n = 0; n < cube.frameCount(); ++n) {
    cube.frame(n)[25 * cube.width() + 26] = 1e6f;  // a hot pixel, masked
    cube.mask()[n * cube.framePixels() + 25 * cube.width() + 26] = 1;
  }
  const FitResult r = fitComoving(cube, {{1.0, 0.0}, 24.0, 24.0, std::nan(""), 0.0}, paperOptions());
  ASSERT_TRUE(r.ok()) << r.message;
  EXPECT_NEAR(r.params.xc, src.x, 2e-3);
}

TEST(ComovingFit, FailuresAreStatusesNotNaNs) {
  // Nothing at all: the amplitude estimate is 0, the position is undetermined.
  FrameCube zero = makeEmptyCube(32, 10, 0.06);
  const FitResult a = fitComoving(zero, {{0.0, 0.0}, 16.0, 16.0, std::nan(""), 0.0}, paperOptions());
  EXPECT_EQ(a.status, FitStatus::Singular);
  EXPECT_FALSE(a.message.empty());
  // Outside the frame.
  const FitResult b = fitComoving(zero, {{0.0, 0.0}, -40.0, 16.0, 1.0, 0.0}, paperOptions());
  EXPECT_EQ(b.status, FitStatus::LeftFrame);
  // Pure noise far from any source: some failure or a weak "detection", never NaN.
  for (std::uint64_t seed = 1; seed <= 5; ++seed) {
    FrameCube noise = makeEmptyCube(40, 30, 0.06);
    addNoise(noise, 2.0, false, seed);
    FitOptions o = paperOptions();
    o.sigmaN = 2.0;
    const FitResult c = fitComoving(noise, {{1.0, 0.5}, 20.0, 20.0, std::nan(""), 0.0}, o);
    EXPECT_TRUE(c.params.toVector().allFinite());
    EXPECT_TRUE(std::isfinite(c.snr));
    if (c.ok())
      EXPECT_LT(c.snr, 6.0);
    else
      EXPECT_FALSE(c.message.empty());
  }
  EXPECT_THROW((void)fitComoving(zero, {{0, 0}, 1, 1, 1, 0},
                                 [] {
                                   FitOptions o;
                                   o.psf.beta = 0.5;
                                   return o;
                                 }()),
               InputError);
}

TEST(ComovingFit, ASaturatedStarEndsWithAClearStatusAndAWarning) {
  const MovingSource src{20.3, 20.6, {0.0, 0.0}, 2e5};
  FrameCube cube = movingCube(src, 10, 0.0, 0, 40);
  for (float& v : cube.pixels())
    v = std::min(v, 3000.0f);  // clipped core
  addNoise(cube, 2.0, false, 3);
  FitOptions o = paperOptions();
  o.sigmaN = 2.0;
  const FitResult r = fitComoving(cube, {{0.0, 0.0}, 20.0, 21.0, std::nan(""), 0.0}, o);
  EXPECT_TRUE(r.params.toVector().allFinite());
  if (r.ok()) {
    ASSERT_FALSE(r.warnings.empty());
    EXPECT_NE(r.warnings[0].find("reduced chi^2"), std::string::npos);
  }
}

TEST(ComovingFit, CancelStopsIt) {
  const FrameCube cube = movingCube({24, 24, {1, 0}, 500}, 10, 1.0, 1);
  CancelToken cancel;
  cancel.cancel();
  EXPECT_THROW((void)fitComoving(cube, {{1, 0}, 24, 24, std::nan(""), 0}, paperOptions(), {}, cancel),
               Cancelled);
}

}  // namespace
}  // namespace st::fit

namespace st::fit {
namespace {

TEST(ComovingFit, HessianErrorsMatchEqSigWhenBackgroundLimited) {
  // N_ph = 150, sigma_n = 10: eq:sig's background term is 30x the photon term.
  const MovingSource src{24.2, 23.7, {2.0, 1.0}, 150.0};
  const FrameCube cube = movingCube(src, 50, 10.0, 5);
  FitOptions o = paperOptions();
  o.sigmaN = 10.0;
  const FitResult r = fitComoving(cube, {{2.1, 0.9}, 24.0, 24.0, std::nan(""), 0.0}, o);
  ASSERT_TRUE(r.ok()) << r.message;
  EXPECT_NEAR(r.sigma[kXc] / r.sigmaPosPaper, 1.0, 0.10);
  EXPECT_NEAR(r.sigma[kYc] / r.sigmaPosPaper, 1.0, 0.10);
  EXPECT_NEAR(r.sigma[kVy] / r.sigmaVelPaper, 1.0, 0.10);
  EXPECT_NEAR(r.sigmaPosSnr / r.sigmaPosPaper, 1.0, 0.15);
}

}  // namespace
}  // namespace st::fit

namespace st::fit {
namespace {

TEST(PixelPsf, TableMatchesTheExactEvaluation) {
  for (const psf::Moffat m : {psf::Moffat{3.3, 4.0}, psf::Moffat{3.0, 2.5}, psf::Moffat{5.0, 6.3}}) {
    const PixelPsfTable t(m, 28.0);
    double worst = 0.0, worstGrad = 0.0;
    for (double u = -30.0; u <= 30.0; u += 0.37) {
      for (double v = -30.0; v <= 30.0; v += 0.53) {
        const PsfSample a = pixelPsf(m, u, v), b = t.sample(u, v);
        worst = std::max({worst, std::abs(a.value - b.value), std::abs(t.value(u, v) - a.value)});
        worstGrad = std::max({worstGrad, std::abs(a.du - b.du), std::abs(a.dv - b.dv)});
      }
    }
    EXPECT_LT(worst, 3e-6);
    EXPECT_LT(worstGrad, 3e-6);
  }
}

}  // namespace
}  // namespace st::fit

// PSF: Moffat fit by Levenberg-Marquardt (paper \label{MoffatPsf}), radial profile, star selection.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "st/common/error.hpp"
#include "st/psf/moffat.hpp"
#include "st/psf/moffat_fit.hpp"
#include "st/psf/psf_star.hpp"

namespace st::psf {
namespace {

/// Adds amp x (the mean of P over each pixel by a 16 x 16 midpoint rule: another quadrature than the fit's
/// Gauss-Legendre one, so the test does not fit its own discretisation) centred at (x0, y0).
void addStar(Image& img, double x0, double y0, const Moffat& m, double amp, int half = 20) {
  constexpr int kSub = 16;
  for (int y = std::max(0, int(y0) - half); y <= std::min(img.height - 1, int(y0) + half); ++y)
    for (int x = std::max(0, int(x0) - half); x <= std::min(img.width - 1, int(x0) + half); ++x) {
      double sum = 0.0;
      for (int j = 0; j < kSub; ++j)
        for (int i = 0; i < kSub; ++i)
          sum += m(x - x0 + (i + 0.5) / kSub - 0.5, y - y0 + (j + 0.5) / kSub - 0.5);
      img.at(x, y) += static_cast<float>(amp * sum / (kSub * kSub));
    }
}

void addNoise(Image& img, double bg, double sigma, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> g(0.0f, float(sigma));
  for (auto& p : img.pixels)
    p += float(bg) + g(rng);
}

TEST(Moffat, FwhmFallbackAndTruncationRadius) {
  const Moffat m = Moffat::fromFwhm(3.0);
  EXPECT_DOUBLE_EQ(m.beta, 4.0);
  EXPECT_NEAR(m.fwhm(), 3.0, 1e-12);
  // Paper §3.3: R = 3.3, beta = 4 -> W = 2 * 3.3 * sqrt(2^0.25 - 1) = 2.868 px.
  EXPECT_NEAR((Moffat{3.3, 4.0}).fwhm(), 2.87086, 1e-5);
  const Moffat paper{3.3, 4.0};
  const double rTrunc = paper.radiusAtFraction(1e-3);
  EXPECT_NEAR(paper(rTrunc, 0.0), 1e-3, 1e-12);
  EXPECT_NEAR(rTrunc, 7.10, 0.01);
}

// Peak SNR = amplitude / sigma = 20000 / 10 = 2000: a bright PSF star in a sky-rate stack, the case this
// stage is for. At this SNR the fit's own sigma_beta is ~0.4%, so 2% is a 5-sigma bound.
TEST(MoffatFit, RecoversRadiusAndBetaWithin2PercentOnNoisyStar) {
  const Moffat truth{3.3, 4.0};
  for (unsigned seed = 1; seed <= 5; ++seed) {
    Image img(64, 64);
    addStar(img, 31.37, 32.81, truth, 20000.0);
    addNoise(img, 100.0, 10.0, seed);
    const MoffatFit fit = fitMoffat(img, 31.0, 33.0);
    ASSERT_TRUE(fit.converged()) << toString(fit.convergence);
    EXPECT_NEAR(fit.model.radius, truth.radius, 0.02 * truth.radius) << "seed " << seed;
    EXPECT_NEAR(fit.model.beta, truth.beta, 0.02 * truth.beta) << "seed " << seed;
    EXPECT_NEAR(fit.x0, 31.37, 0.01);
    EXPECT_NEAR(fit.y0, 32.81, 0.01);
    EXPECT_NEAR(fit.amplitude, 20000.0, 0.01 * 20000.0);
    EXPECT_NEAR(fit.background, 100.0, 1.0);
    EXPECT_NEAR(fit.fwhm(), truth.fwhm(), 0.01 * truth.fwhm());
    EXPECT_NEAR(fit.residualRms, 10.0, 0.6);
  }
}

// Peak SNR 200: beta is only good to ~4% there, but the reported 1-sigma uncertainties must be honest: over
// 20 noise realisations the rms of (fit - truth) / sigma is ~1 (0.6..1.5) for R, beta, x0 and W.
TEST(MoffatFit, ReportedUncertaintiesMatchTheScatter) {
  const Moffat truth{3.3, 4.0};
  double zR = 0, zB = 0, zX = 0, zW = 0;
  constexpr int kRuns = 20;
  for (unsigned seed = 100; seed < 100 + kRuns; ++seed) {
    Image img(48, 48);
    addStar(img, 23.6, 24.2, truth, 2000.0, 24);
    addNoise(img, 100.0, 10.0, seed);
    const MoffatFit fit = fitMoffat(img, 24.0, 24.0);
    ASSERT_TRUE(fit.converged());
    zR += std::pow((fit.model.radius - truth.radius) / fit.sigmaRadius, 2);
    zB += std::pow((fit.model.beta - truth.beta) / fit.sigmaBeta, 2);
    zX += std::pow((fit.x0 - 23.6) / fit.sigmaX0, 2);
    zW += std::pow((fit.fwhm() - truth.fwhm()) / fit.sigmaFwhm, 2);
  }
  for (double z : {zR, zB, zX, zW}) {
    EXPECT_GT(std::sqrt(z / kRuns), 0.6);
    EXPECT_LT(std::sqrt(z / kRuns), 1.5);
  }
}

TEST(MoffatFit, NoiselessStarIsExactAndPointSamplingWouldBeBiased) {
  const Moffat truth{1.6, 2.5};  // FWHM 2.0 px: pixel integration matters most for small PSFs
  Image img(40, 40);
  addStar(img, 20.2, 19.7, truth, 500.0);
  const MoffatFit fit = fitMoffat(img, 20.0, 20.0);
  ASSERT_TRUE(fit.converged()) << toString(fit.convergence);
  EXPECT_NEAR(fit.model.radius, truth.radius, 2e-3 * truth.radius);
  EXPECT_NEAR(fit.model.beta, truth.beta, 2e-3 * truth.beta);
  MoffatFitOptions point;
  point.subsamples = 1;
  const MoffatFit biased = fitMoffat(img, 20.0, 20.0, point);
  EXPECT_GT(biased.fwhm(), truth.fwhm() * 1.02);  // why the fit integrates over pixels
}

TEST(MoffatFit, RadialProfileFollowsTheFit) {
  const Moffat truth{3.3, 4.0};
  Image img(64, 64);
  addStar(img, 30.5, 31.5, truth, 1000.0);
  addNoise(img, 50.0, 2.0, 7);
  const MoffatFit fit = fitMoffat(img, 30.0, 31.0);
  const auto prof = radialProfile(img, fit, 12.0, 1.0);
  ASSERT_GE(prof.size(), 10u);
  EXPECT_LT(prof.front().radius, 1.0);
  EXPECT_GT(prof.front().mean, 700.0);
  for (const auto& b : prof) {
    EXPECT_NEAR(b.mean, b.model, 4.0 * 2.0 / std::sqrt(double(b.count)) + 1e-3 * fit.amplitude) << b.radius;
  }
  for (std::size_t i = 1; i < prof.size(); ++i)
    EXPECT_LT(prof[i].model, prof[i - 1].model);
}

TEST(PsfStar, ChoosesIsolatedUnsaturatedStar) {
  const Moffat truth{2.6, 3.5};
  Image img(200, 160);
  addStar(img, 50.3, 60.6, truth, 40000.0);  // brightest, but clipped at 20000 below: saturated
  addStar(img, 150.7, 40.2, truth, 8000.0);  // bright but with a close companion
  addStar(img, 156.0, 44.0, truth, 3000.0);
  addStar(img, 100.4, 120.3, truth, 5000.0);  // the one to choose
  addStar(img, 30.0, 130.0, truth, 800.0);
  addNoise(img, 200.0, 8.0, 3);
  for (auto& p : img.pixels)
    p = std::min(p, 20000.0f);
  PsfStarOptions opt;
  opt.saturationLevel = 20000.0;
  const PsfMeasurement m = measurePsf(img, {}, opt);
  EXPECT_NEAR(m.star.x, 100.0, 1.0);
  EXPECT_NEAR(m.star.y, 120.0, 1.0);
  EXPECT_NEAR(m.fit.model.radius, truth.radius, 0.03 * truth.radius);
  EXPECT_NEAR(m.fit.fwhm(), truth.fwhm(), 0.02 * truth.fwhm());

  // The same from a catalog passed in (static-source catalog), and the star a user names.
  const std::vector<StarCandidate> catalog{{50.3, 60.6, 1e6, true}, {100.4, 120.3, 5e4, false}};
  EXPECT_NEAR(measurePsf(img, catalog, opt).star.x, 100.4, 1e-9);
  EXPECT_NEAR(measurePsfAt(img, 30.0, 130.0, opt).fit.fwhm(), truth.fwhm(), 0.05 * truth.fwhm());
}

// measurePsf fits its candidates in waves, in parallel: its verdicts must be those of one candidate at a
// time in flux order, whatever maxAccepted (the wave sizes) is. The reference fits each candidate alone (a
// catalogue of one: the same fit, the same judgement where no neighbour crowds it).
TEST(PsfStar, WavesOfParallelFitsJudgeAsOneAtATime) {
  const Moffat truth{2.6, 3.5};
  Image img(400, 300);
  // 12 isolated stars; the 130, 120 and 110 ones peak below minPeakSnr (noise 8) and are rejected. The
  // catalogue gives them fluxes in grid order, so that those rejections fall between acceptances (a wave of
  // k stars then leaves some to a later wave).
  const double amps[12] = {6000, 5500, 130, 5000, 4500, 120, 4000, 3500, 110, 3000, 2800, 2600};
  std::vector<StarCandidate> candidates;
  for (int i = 0; i < 12; ++i) {
    const double x = 60.3 + 90.0 * (i % 4), y = 60.6 + 90.0 * (i / 4);
    addStar(img, x, y, truth, amps[i]);
    candidates.push_back({x, y, 1000.0 - i, false});
  }
  addNoise(img, 200.0, 8.0, 11);
  // The reference: each candidate alone, brightest first (a rejection's reason is in the error's message).
  std::vector<bool> accepted;
  std::vector<double> fwhm;
  std::vector<std::string> why;
  for (const StarCandidate& c : candidates) {
    try {
      const PsfMeasurement one = measurePsf(img, {c}, PsfStarOptions{});
      accepted.push_back(true);
      fwhm.push_back(one.fit.fwhm());
      why.emplace_back();
    } catch (const InputError& e) {
      accepted.push_back(false);
      fwhm.push_back(0.0);
      why.emplace_back(e.what());
    }
  }
  // A rejection before the last acceptance: a wave of k stars then leaves some to a later wave.
  const auto lastAccepted = std::find(accepted.rbegin(), accepted.rend(), true);
  ASSERT_NE(lastAccepted, accepted.rend());
  ASSERT_NE(std::find(accepted.begin(), lastAccepted.base(), false), lastAccepted.base())
      << "no rejection between acceptances: the test would not need a second wave";
  for (const int k : {1, 2, 3, 5, 8, 9, 12}) {
    PsfStarOptions o;
    o.maxAccepted = k;
    const PsfMeasurement m = measurePsf(img, candidates, o);
    // One at a time: considered up to the k-th acceptance.
    int considered = 0, taken = 0;
    std::vector<double> expected;
    std::vector<std::string> rejections;
    for (std::size_t i = 0; i < candidates.size() && taken < k; ++i) {
      ++considered;
      if (accepted[i]) {
        ++taken;
        expected.push_back(fwhm[i]);
      } else {
        rejections.push_back(why[i]);
      }
    }
    std::sort(expected.begin(), expected.end());
    SCOPED_TRACE("maxAccepted " + std::to_string(k));
    EXPECT_EQ(m.candidatesConsidered, considered);
    EXPECT_EQ(m.acceptedFwhm, expected);  // bit for bit
    ASSERT_EQ(m.rejected.size(), rejections.size());
    for (std::size_t r = 0; r < rejections.size(); ++r)
      EXPECT_NE(rejections[r].find(m.rejected[r]), std::string::npos) << m.rejected[r];
  }
}

TEST(PsfStar, NoUsableStarSaysSoAndAsksForFwhm) {
  Image img(100, 100);
  addNoise(img, 10.0, 1.0, 5);
  try {
    (void)measurePsf(img, {});
    FAIL() << "expected st::InputError";
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("no star usable for the PSF"), std::string::npos) << msg;
    EXPECT_NE(msg.find("FWHM"), std::string::npos) << msg;
  }
  // Only a saturated star: still no usable star.
  Image sat(100, 100);
  addStar(sat, 50, 50, Moffat{3.0, 3.0}, 1e5);
  addNoise(sat, 10.0, 1.0, 6);
  for (auto& p : sat.pixels)
    p = std::min(p, 30000.0f);
  EXPECT_THROW((void)measurePsf(sat, {}), InputError);
  EXPECT_THROW((void)fitMoffat(sat, -5.0, 10.0), InputError);
}

}  // namespace
}  // namespace st::psf

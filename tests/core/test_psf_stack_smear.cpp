// The smear of an integer-shift stack (st/psf/stack_smear.hpp) and the Moffat fit that models it. Oracles:
// the moments of the smear from its definition (trail uniform over v * exposure, shift residuals), and a
// noise-free smeared Moffat (paper \label{MoffatPsf}) whose R and beta the fit must return.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <vector>

#include "st/common/error.hpp"
#include "st/psf/moffat_fit.hpp"
#include "st/psf/psf_star.hpp"
#include "st/psf/stack_smear.hpp"
#include "test_support.hpp"

namespace st::psf {
namespace {

// paper-neo's cadence: 16.7 Hz frame transfer, the sky drifting 16.39 px/s along x.
FrameCube paperNeoCadence(std::size_t frames) {
  FrameCube cube(8, 8, frames);
  for (std::size_t n = 0; n < frames; ++n) {
    cube.info()[n].mjdMid = 56546.3 + (static_cast<double>(n) / 16.7) / 86400.0;
    cube.info()[n].exposureS = 1.0 / 16.7;
  }
  return cube;
}

TEST(StackSmear, MomentsMatchTrailAndShiftResiduals) {
  const FrameCube cube = paperNeoCadence(500);
  const Velocity v{16.39, 0.0};
  const SmearKernel k = stackSmear(cube, v, 0.125);
  ASSERT_FALSE(k.empty());
  double sum = 0.0, mx = 0.0, my2 = 0.0;
  for (std::size_t i = 0; i < k.weight.size(); ++i) {
    sum += k.weight[i];
    mx += k.weight[i] * k.dx[i];
    my2 += k.weight[i] * k.dy[i] * k.dy[i];
  }
  EXPECT_NEAR(sum, 1.0, 1e-12);
  EXPECT_NEAR(mx, 0.0, 0.02);
  EXPECT_EQ(my2, 0.0);
  double var = 0.0;
  for (std::size_t i = 0; i < k.weight.size(); ++i)
    var += k.weight[i] * (k.dx[i] - mx) * (k.dx[i] - mx);
  // Trail (16.39 / 16.7 px, uniform): L^2 / 12; residuals ~ uniform on [-0.5, 0.5]: 1 / 12; binning 1/8 px
  // adds ~(1/8)^2 / 12.
  const double trail = 16.39 / 16.7;
  EXPECT_NEAR(var, trail * trail / 12.0 + 1.0 / 12.0 + 0.125 * 0.125 / 12.0, 0.006);
}

TEST(StackSmear, TrackedUntrailedStackHasNone) {
  const FrameCube cube = paperNeoCadence(50);
  EXPECT_TRUE(stackSmear(cube, Velocity{0.0, 0.0}).empty());
}

// A noise-free star as a paper-neo sky-rate stack records it: R = 3, beta = 2.5 (FWHM 2.93 px), smeared.
Image smearedStar(const Moffat& m, const SmearKernel& k, double x0, double y0) {
  Image img(41, 41);
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) {
      double v = 0.0;
      for (std::size_t i = 0; i < k.weight.size(); ++i)
        v += k.weight[i] * m.pixelMean(x - x0 - k.dx[i], y - y0 - k.dy[i], 5);
      img.at(x, y) = static_cast<float>(10.0 + 1000.0 * v);
    }
  return img;
}

TEST(MoffatFitSmear, ModelledSmearReturnsThePsfItself) {
  const Moffat truth{3.0, 2.5};
  const SmearKernel k = stackSmear(paperNeoCadence(500), Velocity{16.39, 4.0});
  const Image img = smearedStar(truth, k, 20.3, 19.8);
  MoffatFitOptions o;
  o.smear = k;
  const MoffatFit fit = fitMoffat(img, 20.0, 20.0, o);
  ASSERT_TRUE(fit.converged()) << toString(fit.convergence);
  EXPECT_NEAR(fit.model.radius, truth.radius, 0.002 * truth.radius);
  EXPECT_NEAR(fit.model.beta, truth.beta, 0.002 * truth.beta);
  EXPECT_NEAR(fit.fwhm(), truth.fwhm(), 0.001 * truth.fwhm());
  EXPECT_NEAR(fit.amplitude, 1000.0, 1.0);
  // Ignoring the smear (what the pipeline did) returns a PSF > 2% too wide: the defect this guards against.
  const MoffatFit plain = fitMoffat(img, 20.0, 20.0, {});
  EXPECT_GT(plain.fwhm(), 1.02 * truth.fwhm());
}

// Deterministic noise (a fixed linear congruential sequence, uniform, rms ~ `amplitude` / sqrt(3)).
void addNoise(Image& img, double amplitude, std::uint64_t seed) {
  for (float& v : img.pixels) {
    seed = seed * 6364136223846793005ull + 1442695040888963407ull;
    v += static_cast<float>(amplitude * (2.0 * static_cast<double>(seed >> 11) / 9007199254740992.0 - 1.0));
  }
}

void expectSameFit(const MoffatFit& a, const MoffatFit& b) {
  EXPECT_EQ(a.x0, b.x0);
  EXPECT_EQ(a.y0, b.y0);
  EXPECT_EQ(a.model.radius, b.model.radius);
  EXPECT_EQ(a.model.beta, b.model.beta);
  EXPECT_EQ(a.amplitude, b.amplitude);
  EXPECT_EQ(a.background, b.background);
  EXPECT_EQ(a.residualRms, b.residualRms);
  EXPECT_EQ(a.sigmaFwhm, b.sigmaFwhm);
  EXPECT_EQ(a.iterations, b.iterations);
}

// The fit computes its pixels' models on every core and sums them in pixel order (issue 16): the same fit,
// bit for bit, on one thread as on several (3 and 4: chunks of uneven and even split).
TEST(MoffatFitSmear, SameFitBitForBitOnOneThreadAndOnSeveral) {
  const SmearKernel k = stackSmear(paperNeoCadence(500), Velocity{16.39, 4.0});
  Image img = smearedStar(Moffat{3.0, 2.5}, k, 20.3, 19.8);
  addNoise(img, 20.0, 7);
  MoffatFitOptions o;
  o.smear = k;
  MoffatFit one;
  {
    const test::ScopedThreads threads("1");
    one = fitMoffat(img, 20.0, 20.0, o);
  }
  ASSERT_TRUE(one.converged()) << toString(one.convergence);
  EXPECT_GT(one.iterations, 3);
  for (const char* n : {"3", "4"}) {
    const test::ScopedThreads threads(n);
    expectSameFit(fitMoffat(img, 20.0, 20.0, o), one);
  }
}

// measurePsf fits the candidates one at a time, brightest first, until maxAccepted are accepted: the same PSF
// and the same rejections on one thread as on four.
TEST(MoffatFitSmear, MeasurePsfIsTheSameOnOneThreadAndOnFour) {
  const SmearKernel k = stackSmear(paperNeoCadence(200), Velocity{16.39, 0.0});
  Image img(200, 120, 10.0f);
  std::vector<StarCandidate> stars;
  const Moffat m{3.2, 3.0};
  for (int i = 0; i < 6; ++i) {
    const double x0 = 30.0 + 28.0 * i + 0.1 * i, y0 = 40.0 + 9.0 * (i % 3) + 0.17 * i;
    const double flux = 4000.0 - 500.0 * i;
    for (int y = 0; y < img.height; ++y)
      for (int x = 0; x < img.width; ++x) {
        double v = 0.0;
        for (std::size_t j = 0; j < k.weight.size(); ++j)
          v += k.weight[j] * m.pixelMean(x - x0 - k.dx[j], y - y0 - k.dy[j], 3);
        img.at(x, y) += static_cast<float>(flux * v);
      }
    stars.push_back({std::round(x0), std::round(y0), flux, false});
  }
  addNoise(img, 6.0, 11);
  PsfStarOptions o;
  o.fit.smear = k;
  o.maxAccepted = 4;
  PsfMeasurement one;
  {
    const test::ScopedThreads threads("1");
    one = measurePsf(img, stars, o);
  }
  const test::ScopedThreads threads("4");
  const PsfMeasurement four = measurePsf(img, stars, o);
  expectSameFit(four.fit, one.fit);
  EXPECT_EQ(four.candidatesConsidered, one.candidatesConsidered);
  EXPECT_EQ(four.rejected, one.rejected);
  EXPECT_EQ(four.acceptedFwhm, one.acceptedFwhm);
  EXPECT_EQ(one.acceptedFwhm.size(), 4u);
  EXPECT_NEAR(one.fit.fwhm(), m.fwhm(), 0.05 * m.fwhm());
}

// A fit far below the caller's amplitude (MoffatFitOptions::rejectBelowAmplitude, measurePsf's minPeakSnr x
// noise) is not refined with the smear: it is rejected either way. Oracle: the fit without the option. Every
// star whose full fit reaches the amplitude gets the same fit bit for bit; the ones left unrefined are below
// it in the full fit too, and in their own; and the faint end is left unrefined (peak SNR 3 to 150 against
// 20, noise rms 6; a plain fit that does not converge is not refined either way). Also for a trail 5 times
// paper-neo's, longer than the star, where the plain fit's profile is more the smear's than the PSF's.
TEST(MoffatFitSmear, FitsTooFaintForTheCallerAreNotRefined) {
  // paper-neo's trail (~1 px a frame), and one 5 times as long (~5 px: longer than the star).
  for (const double rate : {16.39, 82.0}) {
    SCOPED_TRACE("sky rate " + std::to_string(rate) + " px/s");
    const SmearKernel k = stackSmear(paperNeoCadence(100), Velocity{rate, 0.0});
    ASSERT_FALSE(k.empty());
    const double noiseRms = 6.0, threshold = 20.0 * noiseRms;
    int unrefined = 0, same = 0;
    std::uint64_t seed = 3;
    const bool longTrail = rate > 20.0;  // its fits cost ~5x: the SNRs around the threshold, and faint ones
    const std::vector<double> snrs = longTrail
                                         ? std::vector<double>{3.0, 4.0, 5.0, 20.0, 25.0, 30.0, 40.0}
                                         : std::vector<double>{3.0,  4.0,  5.0,  6.0,  7.0,  9.0,  11.0,
                                                               14.0, 18.0, 22.0, 30.0, 45.0, 80.0, 150.0};
    for (const double snr : snrs) {
      Image img = smearedStar(Moffat{2.6, 3.5}, k, 20.3, 19.6);
      for (float& v : img.pixels)  // smearedStar's amplitude 1000 above 10 -> snr x noiseRms
        v = static_cast<float>(10.0 + (v - 10.0) * snr * noiseRms / 1000.0);
      addNoise(img, noiseRms * std::sqrt(3.0), ++seed);
      MoffatFitOptions o;
      o.smear = k;
      const MoffatFit full = fitMoffat(img, 20.0, 20.0, o);
      o.rejectBelowAmplitude = threshold;
      const MoffatFit fast = fitMoffat(img, 20.0, 20.0, o);
      const bool identical = fast.x0 == full.x0 && fast.y0 == full.y0 &&
                             fast.model.radius == full.model.radius && fast.model.beta == full.model.beta &&
                             fast.amplitude == full.amplitude && fast.iterations == full.iterations;
      if (identical) {
        ++same;
        continue;
      }
      ++unrefined;
      EXPECT_LT(full.amplitude, threshold) << "SNR " << snr << ": a fit the caller accepts was not refined";
      EXPECT_LT(fast.amplitude, threshold) << "SNR " << snr;
      EXPECT_LT(fast.iterations, full.iterations) << "SNR " << snr;
    }
    EXPECT_GE(unrefined, longTrail ? 1 : 3);
    EXPECT_GE(same, longTrail ? 3 : 5);
  }
}

// A plain fit pinned at the beta bound is refined with the smear when it stays at its star (a trail the
// plain model cannot follow may pin beta), and returned as it is when it also strayed from it (a faint star
// beside a bright flat-topped blob: the fit runs to the blob; refining that ran to the iteration limit on the
// widest stamps, for a fit rejected all the same).
TEST(MoffatFitSmear, PinnedPlainFitIsRefinedOnlyWhereItStaysAtItsStar) {
  MoffatFitOptions o;
  o.smear = stackSmear(paperNeoCadence(500), Velocity{16.39, 4.0});
  ASSERT_FALSE(o.smear.empty());
  o.halfSize = 8;  // 17 x 17 pixels: the refinement of a flat disc may run to the iteration limit
  MoffatFitOptions plainOptions;
  plainOptions.halfSize = o.halfSize;
  Image disc(61, 61, 10.0f);
  for (int y = 0; y < disc.height; ++y)
    for (int x = 0; x < disc.width; ++x)
      if (std::hypot(x - 30.2, y - 29.7) <= 5.0) disc.at(x, y) += 5000.0f;
  addNoise(disc, 3.0, 5);
  const MoffatFit plainAtStar = fitMoffat(disc, 30.0, 30.0, plainOptions);
  ASSERT_TRUE(plainAtStar.converged()) << toString(plainAtStar.convergence);
  ASSERT_TRUE(betaAtFitBound(plainAtStar.model.beta)) << plainAtStar.model.beta;
  const MoffatFit refined = fitMoffat(disc, 30.0, 30.0, o);
  EXPECT_NE(refined.model.radius, plainAtStar.model.radius);
  EXPECT_GT(refined.iterations, plainAtStar.iterations);

  // A faint star at the guess, and 28 px off a broad Gaussian glow (beta -> infinity: pinned at the bound).
  Image blob(61, 61, 10.0f);
  const Moffat faint{2.0, 3.0};
  for (int y = 0; y < blob.height; ++y)
    for (int x = 0; x < blob.width; ++x) {
      const double r2 = (x - 40.0) * (x - 40.0) + (y - 30.0) * (y - 30.0);
      blob.at(x, y) += static_cast<float>(40.0 * faint.pixelMean(x - 12.0, y - 30.0, 3) +
                                          2000.0 * std::exp(-0.5 * r2 / 36.0));
    }
  addNoise(blob, 3.0, 9);
  MoffatFitOptions wide = o, wideOptions = plainOptions;
  wide.halfSize = wideOptions.halfSize = 30;
  const MoffatFit plainStrayed = fitMoffat(blob, 12.0, 30.0, wideOptions);
  ASSERT_TRUE(plainStrayed.converged()) << toString(plainStrayed.convergence);
  ASSERT_TRUE(betaAtFitBound(plainStrayed.model.beta))
      << plainStrayed.model.beta << " R " << plainStrayed.model.radius << " at " << plainStrayed.x0 << ", "
      << plainStrayed.y0;
  ASSERT_GT(std::hypot(plainStrayed.x0 - 12.0, plainStrayed.y0 - 30.0),
            std::max(3.0, plainStrayed.fwhm()) + 2.0)
      << plainStrayed.x0 << ", " << plainStrayed.y0 << " FWHM " << plainStrayed.fwhm();
  expectSameFit(fitMoffat(blob, 12.0, 30.0, wide), plainStrayed);
}

TEST(MoffatFitSmear, MismatchedKernelThrows) {
  MoffatFitOptions o;
  o.smear.dx = {0.0, 0.1};
  o.smear.dy = {0.0};
  o.smear.weight = {0.5, 0.5};
  EXPECT_THROW((void)fitMoffat(Image(30, 30, 1.0f), 15.0, 15.0, o), InputError);
}

}  // namespace
}  // namespace st::psf

// The Moffat fit's model in four lanes (core/psf/moffat_samples.cpp), white-box: its exp and log against the
// C library's (within 1 ulp where they are its own, the library's value outside), the AVX2 lanes against the
// scalar lanes (every bit), and the model and its gradient against the model of before (std::exp and
// std::log sample by sample) and against finite differences.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

#include "../../core/psf/moffat_samples.hpp"  // white-box: the model's lanes
#include "st/psf/moffat_fit.hpp"

namespace st::psf::detail {
namespace {

// Units in the last place between a and b (finite, same sign).
std::int64_t ulps(double a, double b) {
  const auto ia = std::bit_cast<std::int64_t>(a), ib = std::bit_cast<std::int64_t>(b);
  return ia > ib ? ia - ib : ib - ia;
}

TEST(MoffatLanes, ExpAndLogWithinAnUlpOfTheLibraryAndItsValueOutsideTheirRange) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> expArg(-699.9, 699.9), small(-3.0, 3.0), logExp(-1021.0, 1023.0);
  std::int64_t worstExp = 0, worstLog = 0;
  for (int i = 0; i < 400000; ++i) {
    const double x = i % 2 ? expArg(rng) : small(rng);
    worstExp = std::max(worstExp, ulps(laneExp(x), std::exp(x)));
    // Over the whole normal range, and (as the model's u = 1 + r^2 / R^2) just above 1.
    const double y = i % 2 ? std::exp2(logExp(rng))
                           : 1.0 + std::ldexp(1.0, -static_cast<int>(rng() % 50)) *
                                       static_cast<double>(rng() % 1000) / 1000.0;
    worstLog = std::max(worstLog, ulps(laneLog(y), std::log(y)));
  }
  EXPECT_LE(worstExp, 1);
  EXPECT_LE(worstLog, 1);
  EXPECT_EQ(laneLog(1.0), 0.0);
  EXPECT_EQ(laneExp(0.0), 1.0);
  // Outside: the library's values (zero, negatives, subnormals, infinities, NaN; |x| >= 700).
  const double denorm = std::numeric_limits<double>::denorm_min();
  for (const double x : {0.0, -1.0, denorm, std::numeric_limits<double>::infinity()})
    EXPECT_EQ(std::bit_cast<std::uint64_t>(laneLog(x)), std::bit_cast<std::uint64_t>(std::log(x))) << x;
  for (const double x : {-745.0, -700.0, 700.0, 709.0, 1e300})
    EXPECT_EQ(laneExp(x), std::exp(x)) << x;
  EXPECT_TRUE(std::isnan(laneLog(std::nan(""))));
  EXPECT_TRUE(std::isnan(laneExp(std::nan(""))));
}

TEST(MoffatLanes, FourLanesGiveTheScalarBitsInsideAndOutsideTheRange) {
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> arg(-800.0, 800.0), mag(-1074.0, 1100.0);
  int lanes = 0;
  for (int i = 0; i < 50000; ++i) {
    double x[4], y[4], e[4], l[4];
    for (int k = 0; k < 4; ++k) {
      x[k] = arg(rng);
      y[k] = std::exp2(mag(rng));  // subnormal to infinite
    }
    if (i % 97 == 0) x[i % 4] = std::nan(""), y[(i + 1) % 4] = -2.0;
    laneExp4(x, e);
    laneLog4(y, l);
    for (int k = 0; k < 4; ++k, ++lanes) {
      const double se = laneExp(x[k]), sl = laneLog(y[k]);
      if (std::isnan(se)) {
        EXPECT_TRUE(std::isnan(e[k]));
      } else {
        ASSERT_EQ(std::bit_cast<std::uint64_t>(e[k]), std::bit_cast<std::uint64_t>(se)) << x[k];
      }
      if (std::isnan(sl)) {
        EXPECT_TRUE(std::isnan(l[k]));
      } else {
        ASSERT_EQ(std::bit_cast<std::uint64_t>(l[k]), std::bit_cast<std::uint64_t>(sl)) << y[k];
      }
    }
  }
  EXPECT_EQ(lanes, 200000);
  if (!moffatLanesAvx2()) GTEST_SKIP() << "no AVX2 here: the four lanes ran as scalars";
}

// A smear of `k` offsets along a trail (the stack_smear shape), weights summing to 1.
SmearKernel trail(int k, double lengthPx, double angle) {
  SmearKernel s;
  for (int i = 0; i < k; ++i) {
    const double t = k == 1 ? 0.0 : lengthPx * (static_cast<double>(i) / (k - 1) - 0.5);
    s.dx.push_back(t * std::cos(angle) + 0.13);
    s.dy.push_back(t * std::sin(angle) - 0.07);
    s.weight.push_back(1.0 / k);
  }
  return s;
}

TEST(MoffatLanes, ModelAndGradientMatchTheModelOfBeforeAndFiniteDifferences) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> centre(-3.0, 3.0), radius(0.6, 6.0), beta(1.2, 8.0),
      angle(0.0, 3.14);
  double worstValue = 0.0, worstGrad = 0.0, worstFd = 0.0;
  for (int t = 0; t < 300; ++t) {
    const int rule = 1 + t % 5;
    const Moffat::GaussRule g = Moffat::gaussRule(rule);
    const SmearKernel smear =
        t % 3 == 0 ? SmearKernel{{0.0}, {0.0}, {1.0}} : trail(3 + t % 9, 4.0, angle(rng));
    const MoffatSamples samples = moffatSamples(g, smear);
    ASSERT_EQ(samples.weight.size() % 4, 0u);
    const double p[6] = {centre(rng), centre(rng), radius(rng), beta(rng), 1000.0, 50.0};
    for (int q = 0; q < 20; ++q) {
      const double px = std::round(centre(rng) * 4.0), py = std::round(centre(rng) * 4.0);
      double grad[6], scalarGrad[6], ref[6];
      const double v = moffatModelAt(p, px, py, samples, grad);
      const double vs = moffatModelAtLanes(p, px, py, samples, scalarGrad, false);
      ASSERT_EQ(std::bit_cast<std::uint64_t>(v), std::bit_cast<std::uint64_t>(vs));
      for (int k = 0; k < 6; ++k)
        ASSERT_EQ(std::bit_cast<std::uint64_t>(grad[k]), std::bit_cast<std::uint64_t>(scalarGrad[k])) << k;
      const double r = moffatModelAtLibm(p, px, py, g, smear, ref);
      worstValue = std::max(worstValue, std::fabs(v - r) / std::fabs(r));
      // The gradient against the model of before, relative to the largest of its components (those that
      // cancel to near zero by symmetry are compared at that scale).
      const double scale = std::max(
          {std::fabs(ref[kX0]), std::fabs(ref[kY0]), std::fabs(ref[kR]), std::fabs(ref[kBeta]), 1e-300});
      for (int k = 0; k < 4; ++k)
        worstGrad = std::max(worstGrad, std::fabs(grad[k] - ref[k]) / scale);
      worstGrad = std::max(worstGrad, std::fabs(grad[kAmp] - ref[kAmp]) / std::fabs(ref[kAmp]));
      EXPECT_EQ(grad[kBg], 1.0);
      // Central differences of the value, parameter by parameter (without the background, which would bury
      // the wings' differences in its rounding).
      for (int k = 0; k < 4; ++k) {
        double a[6], b[6];
        std::copy(p, p + 6, a);
        std::copy(p, p + 6, b);
        a[kBg] = b[kBg] = 0.0;
        const double h = 1e-5 * std::max(1.0, std::fabs(p[k]));
        a[k] += h;
        b[k] -= h;
        const double fd =
            (moffatModelAt(a, px, py, samples, nullptr) - moffatModelAt(b, px, py, samples, nullptr)) /
            (2 * h);
        worstFd = std::max(worstFd, std::fabs(fd - grad[k]) / scale);
      }
    }
  }
  EXPECT_LT(worstValue, 1e-13);
  EXPECT_LT(worstGrad, 1e-12);
  EXPECT_LT(worstFd, 1e-6);
}

// A whole fit with the lanes' model lands where the fit of before landed, within far less than its errors.
TEST(MoffatLanes, AFitOfASmearedStarMatchesTheFitWithTheModelOfBefore) {
  const SmearKernel smear = trail(9, 3.0, 0.4);
  const Moffat truth{2.4, 3.1};
  const int w = 41, h = 41;
  Image img(w, h);
  std::mt19937_64 rng(17);
  std::normal_distribution<double> noise(0.0, 3.0);
  const Moffat::GaussRule g = Moffat::gaussRule(4);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      double v = 0.0;
      for (std::size_t k = 0; k < smear.weight.size(); ++k)
        for (int j = 0; j < g.n; ++j)
          for (int i = 0; i < g.n; ++i)
            v += smear.weight[k] * g.w[i] * g.w[j] *
                 truth(x + g.x[i] - 20.3 - smear.dx[k], y + g.x[j] - 19.6 - smear.dy[k]);
      img.at(x, y) = static_cast<float>(100.0 + 2000.0 * v + noise(rng));
    }
  if (moffatModelLibm()) GTEST_SKIP() << "ST_PSF_LIBM_MODEL=1: the fit of before only";
  MoffatFitOptions o;
  o.smear = smear;
  o.halfSize = 15;
  const MoffatFit fit = fitMoffat(img, 20.0, 20.0, o);
  ASSERT_TRUE(fit.converged());
  EXPECT_NEAR(fit.x0, 20.3, 3 * fit.sigmaX0 + 1e-3);
  EXPECT_NEAR(fit.y0, 19.6, 3 * fit.sigmaY0 + 1e-3);
  EXPECT_NEAR(fit.fwhm(), truth.fwhm(), 3 * fit.sigmaFwhm + 1e-3);
  // The fit with std::exp and std::log sample by sample: the model differs by ~1e-16 relative, so the two
  // minima agree to ~1e-9 of the errors.
  const MoffatFit ref = [&] {
    detail::LibmModelScope scope;
    EXPECT_TRUE(moffatModelLibm());  // else the two fits would be one
    return fitMoffat(img, 20.0, 20.0, o);
  }();
  EXPECT_FALSE(moffatModelLibm());
  EXPECT_NEAR(fit.x0, ref.x0, 1e-6 * fit.sigmaX0);
  EXPECT_NEAR(fit.y0, ref.y0, 1e-6 * fit.sigmaY0);
  EXPECT_NEAR(fit.fwhm(), ref.fwhm(), 1e-6 * fit.sigmaFwhm);
  EXPECT_NEAR(fit.amplitude, ref.amplitude, 1e-6 * fit.sigmaAmplitude);
}

}  // namespace
}  // namespace st::psf::detail

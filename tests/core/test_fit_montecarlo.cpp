// Monte Carlo of the co-moving fit against the paper's precision formulas (§3.3, eq:sig and vel_snr), short
// version for CI: the paper's PSF (R = 3.3, beta = 4), 30 frames, two regimes (photon- and background-
// limited). The longer sweep over photon counts and three noise levels is test_fit_montecarlo_slow.cpp and
// `synthtrack-cli bench fit --montecarlo` (table + plot like the paper's fig_snr).
#include <gtest/gtest.h>

#include <cmath>

#include "montecarlo_checks.hpp"

namespace st::fit {
namespace {

MonteCarloConfig shortConfig(double photons, double sigmaN, std::uint64_t seed) {
  MonteCarloConfig c;
  c.frames = 30;
  c.size = 40;
  c.stampHalfSize = 7;
  c.trials = 100;
  c.photonsPerFrame = photons;
  c.sigmaN = sigmaN;
  c.seed = seed;
  return c;
}

TEST(FitMonteCarlo, PhotonLimitedScatterFollowsEqSig) {
  test::expectAgreesWithPaper(shortConfig(2000.0, 1.0, 21));
}

TEST(FitMonteCarlo, BackgroundLimitedScatterFollowsEqSig) {
  test::expectAgreesWithPaper(shortConfig(100.0, 5.0, 12));
}

}  // namespace
}  // namespace st::fit

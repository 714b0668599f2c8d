#pragma once
// Shared assertions of the fit Monte Carlo tests (paper §3.3): scatter within 20% of eq:sig and vel_snr,
// no bias beyond 3 sigma of the mean, almost every trial converged.
#include <gtest/gtest.h>

#include <cmath>

#include "st/fit/montecarlo.hpp"

namespace st::fit::test {

inline void expectAgreesWithPaper(const MonteCarloConfig& c) {
  CancelToken cancel;
  const MonteCarloPoint p = runMonteCarlo(c, cancel);
  SCOPED_TRACE(::testing::Message() << "N_ph=" << c.photonsPerFrame << " sigma_n=" << c.sigmaN
                                    << " converged=" << p.converged << "/" << c.trials << " sdPos=" << p.sdPos
                                    << " eq:sig=" << p.predictedSigmaPos << " sdVel=" << p.sdVel
                                    << " vel_snr=" << p.predictedSigmaVel << " snr=" << p.meanSnr);
  ASSERT_GE(p.converged, static_cast<int>(0.95 * c.trials));
  EXPECT_NEAR(p.sdPos / p.predictedSigmaPos, 1.0, 0.20);
  EXPECT_NEAR(p.sdVel / p.predictedSigmaVel, 1.0, 0.20);
  const double n = std::sqrt(static_cast<double>(p.converged));
  EXPECT_LT(std::abs(p.meanDx), 3.0 * p.sdX / n);
  EXPECT_LT(std::abs(p.meanDy), 3.0 * p.sdY / n);
  EXPECT_LT(std::abs(p.meanDvx), 3.0 * p.sdVx / n);
  EXPECT_LT(std::abs(p.meanDvy), 3.0 * p.sdVy / n);
  // Photometry is unbiased to 3% and the SNR is the paper's detection_snr for the true amplitude.
  EXPECT_NEAR(p.meanPhotons / c.photonsPerFrame, 1.0, 0.03);
  EXPECT_NEAR(p.meanSnr / p.predictedSnr, 1.0, 0.05);
}

}  // namespace st::fit::test

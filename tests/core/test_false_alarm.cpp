// Prob_false and its inverse (paper §4.5) against values computed with mpmath at 30 digits.
#include <gtest/gtest.h>

#include <cmath>

#include "st/common/error.hpp"
#include "st/stats/false_alarm.hpp"

namespace st::stats {
namespace {

TEST(FalseAlarm, TailProbabilityKnownValues) {
  EXPECT_DOUBLE_EQ(tailProbability(0.0), 0.5);
  // mpmath: erfc(3/sqrt2)/2 = 0.00134989803163009452665, erfc(7/sqrt2)/2 = 1.27981254388583500438e-12.
  EXPECT_NEAR(tailProbability(3.0) / 0.00134989803163009452665 - 1.0, 0.0, 1e-14);
  EXPECT_NEAR(tailProbability(7.0) / 1.27981254388583500438e-12 - 1.0, 0.0, 1e-13);
  EXPECT_NEAR(tailProbability(-3.0), 1.0 - 0.00134989803163009452665, 1e-15);
}

TEST(FalseAlarm, PaperThresholdGivesAboutPointThreePercent) {
  // Paper §4.5: SNR 7, N_x = N_y = 512, N_vx = N_vy = 100 -> "~0.34%". Exactly (mpmath):
  // 2621440000 x 1.27981254388583500438e-12 = 0.00335495179504408331.
  const double p = detectionFap(7.0, 512, 512, 100, 100);
  EXPECT_NEAR(p / 0.00335495179504408331 - 1.0, 0.0, 1e-13);
  EXPECT_LT(p, 0.01);  // the paper's "less than 1% per 30 s of data"
}

TEST(FalseAlarm, ConfirmationUsesTheWindowTrials) {
  // A 9 x 9 px window and 3 x 3 velocities at SNR 7: 729 trials.
  EXPECT_NEAR(confirmationFap(7.0, 9, 9, 3, 3) / (729.0 * 1.27981254388583500438e-12) - 1.0, 0.0, 1e-13);
  EXPECT_LT(confirmationFap(7.0, 9, 9, 3, 3), detectionFap(7.0, 512, 512, 100, 100) * 1e-5);
  EXPECT_DOUBLE_EQ(detectionFap(0.0, 512, 512, 100, 100), 1.0);  // clamped
  EXPECT_NEAR(expectedFalseAlarms(0.0, 10.0), 5.0, 1e-15);       // not clamped
}

TEST(FalseAlarm, LogTailIsContinuousAndFinitePastUnderflow) {
  // At 30 both erfc (4.9067139271481870595e-198) and the asymptotic series are valid.
  EXPECT_NEAR(logTailProbability(29.999999) - std::log(tailProbability(29.999999)), 0.0, 1e-9);
  EXPECT_NEAR(logTailProbability(30.0), std::log(4.90671392714818705953e-198), 1e-12 * 455.0);
  EXPECT_TRUE(std::isfinite(logTailProbability(100.0)));
  // ln Q(100) = -5000 - ln(100 sqrt(2 pi)) + ln(1 - 1e-4 + 3e-8 - ...) (mpmath: -5005.524208694205)
  EXPECT_NEAR(logTailProbability(100.0), -5005.524208694205, 1e-9);
}

TEST(FalseAlarm, ThresholdInversionRoundTrips) {
  const double trials = 512.0 * 512.0 * 100.0 * 100.0;
  // The paper's threshold: Q^{-1}(0.00335495179504408331 / trials) = 7.
  EXPECT_NEAR(snrThresholdForFap(0.00335495179504408331, trials), 7.0, 1e-11);
  for (const double target : {0.5, 0.01, 1e-3, 1e-10, 1e-30, 1e-200}) {
    const double s = snrThresholdForFap(target, trials);
    EXPECT_NEAR((logTailProbability(s) + std::log(trials)) - std::log(target), 0.0, 1e-10) << target;
  }
  EXPECT_NEAR(snrThresholdForFap(0.5, 1.0), 0.0, 1e-12);
}

TEST(FalseAlarm, InversionRejectsImpossibleTargets) {
  EXPECT_THROW(snrThresholdForFap(0.0, 100.0), InputError);
  EXPECT_THROW(snrThresholdForFap(-1.0, 100.0), InputError);
  EXPECT_THROW(snrThresholdForFap(60.0, 100.0), InputError);
  EXPECT_THROW(snrThresholdForFap(0.01, 0.0), InputError);
  EXPECT_THROW(snrThresholdForFap(std::nan(""), 100.0), InputError);
}

}  // namespace
}  // namespace st::stats

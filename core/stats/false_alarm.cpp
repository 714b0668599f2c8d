#include "st/stats/false_alarm.hpp"

#include <cmath>
#include <sstream>

#include "st/common/error.hpp"

namespace st::stats {

namespace {

constexpr double kSqrt2 = 1.4142135623730950488;
constexpr double kLogSqrt2Pi = 0.91893853320467274178;  // ln sqrt(2 pi)
// Below this SNR erfc is used directly; above it the asymptotic series of ln Q (Abramowitz & Stegun
// 7.1.23), whose truncation error at snr = 30 is below 1e-15 relative.
constexpr double kAsymptoticSnr = 30.0;

double clampProbability(double p) {
  return p > 1.0 ? 1.0 : p;
}

}  // namespace

double tailProbability(double snr) {
  return 0.5 * std::erfc(snr / kSqrt2);
}

double logTailProbability(double snr) {
  if (snr < kAsymptoticSnr) return std::log(tailProbability(snr));
  // Q(s) = phi(s)/s * (1 - 1/s^2 + 3/s^4 - 15/s^6 + 105/s^8 - ...)
  const double inv2 = 1.0 / (snr * snr);
  const double series = 1.0 - inv2 * (1.0 - 3.0 * inv2 * (1.0 - 5.0 * inv2 * (1.0 - 7.0 * inv2)));
  return -0.5 * snr * snr - kLogSqrt2Pi - std::log(snr) + std::log(series);
}

double expectedFalseAlarms(double snr, double trials) {
  return trials * tailProbability(snr);
}

double detectionFap(double snr, std::int64_t nx, std::int64_t ny, std::int64_t nvx, std::int64_t nvy) {
  const double trials =
      static_cast<double>(nx) * static_cast<double>(ny) * static_cast<double>(nvx) * static_cast<double>(nvy);
  return clampProbability(expectedFalseAlarms(snr, trials));
}

double confirmationFap(double snr, std::int64_t dnx, std::int64_t dny, std::int64_t dnvx, std::int64_t dnvy) {
  return detectionFap(snr, dnx, dny, dnvx, dnvy);
}

double snrThresholdForFap(double targetFap, double trials) {
  if (!(trials >= 1.0) || !std::isfinite(trials)) {
    std::ostringstream os;
    os << "number of trials must be >= 1, got " << trials;
    throw InputError(os.str());
  }
  if (!(targetFap > 0.0) || !(targetFap <= 0.5 * trials)) {
    std::ostringstream os;
    os << "target false-alarm probability must be in (0, " << 0.5 * trials << "] for " << trials
       << " trials, got " << targetFap;
    throw InputError(os.str());
  }
  // Solve ln Q(s) = ln(target / trials) for s > 0; ln Q is strictly decreasing.
  const double goal = std::log(targetFap) - std::log(trials);
  double lo = 0.0;
  double hi = 1.0;
  while (logTailProbability(hi) > goal)
    hi *= 2.0;
  for (int i = 0; i < 60 && hi - lo > 1e-6 * hi; ++i) {
    const double mid = 0.5 * (lo + hi);
    (logTailProbability(mid) > goal ? lo : hi) = mid;
  }
  // Newton on ln Q: d/ds ln Q(s) = -phi(s)/Q(s) = -exp(ln phi(s) - ln Q(s)).
  double s = 0.5 * (lo + hi);
  for (int i = 0; i < 8; ++i) {
    const double f = logTailProbability(s) - goal;
    const double dlog = -std::exp(-0.5 * s * s - kLogSqrt2Pi - logTailProbability(s));
    const double next = s - f / dlog;
    // The bisection bracket is only 1e-6 wide and its ends can be the root itself: allow a little outside.
    if (!(next > lo - (hi - lo) && next < hi + (hi - lo))) break;
    if (std::abs(next - s) <= 1e-15 * s) {
      s = next;
      break;
    }
    s = next;
  }
  return s;
}

}  // namespace st::stats

#include "st/fit/uncertainty.hpp"

#include <cmath>

namespace st::fit {

double detectionSnr(double alpha, double frames, double sumP2, double sigmaN) noexcept {
  return alpha * std::sqrt(frames) * std::sqrt(sumP2) / sigmaN;
}

double detectionSnrApprox(double nPhotons, double frames, double sigmaN, double fwhm) noexcept {
  return 0.6 * nPhotons * std::sqrt(frames) / (sigmaN * fwhm);
}

double positionSigmaPaper(double nPhotons, double fwhm, double sigmaN, double frames) noexcept {
  const double photon = 0.457 / nPhotons;
  const double background = 1.37 * sigmaN * sigmaN * fwhm * fwhm / (nPhotons * nPhotons);
  return std::sqrt(photon + background) * fwhm / std::sqrt(frames);
}

double positionSigmaFromSnr(double fwhm, double snr) noexcept {
  return 0.65 * fwhm / snr;
}

double velocitySigma(double sigmaXY, double tTotS) noexcept {
  return std::sqrt(12.0) * sigmaXY / tTotS;
}

double effectiveDurationS(const std::vector<double>& timeOffsetsS) noexcept {
  const std::size_t n = timeOffsetsS.size();
  if (n < 2) return 0.0;
  double mean = 0.0;
  for (double t : timeOffsetsS)
    mean += t;
  mean /= static_cast<double>(n);
  double var = 0.0;
  for (double t : timeOffsetsS)
    var += (t - mean) * (t - mean);
  var /= static_cast<double>(n);
  return std::sqrt(12.0 * var);
}

}  // namespace st::fit

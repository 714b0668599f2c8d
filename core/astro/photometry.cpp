#include "st/astro/photometry.hpp"

#include <cmath>
#include <limits>

namespace st::astro {

double photoelectronsPerCount(const FitsHeader& header) {
  const double gain = header.getDouble("GAIN").value_or(header.getDouble("EGAIN").value_or(1.0));
  const double em = header.getDouble("EMGAIN").value_or(1.0);
  const double perCount = gain > 0.0 && std::isfinite(gain) ? gain : 1.0;
  return em > 1.0 && std::isfinite(em) ? perCount / em : perCount;
}

double excessNoiseFactor(const FitsHeader& header) {
  const double em = header.getDouble("EMGAIN").value_or(1.0);
  return em > 1.0 && std::isfinite(em) ? 2.0 : 1.0;
}

double photonsFromAmplitude(double alpha, const psf::Moffat& psf, double gain) noexcept {
  return gain * alpha * psf.integral();
}

double zeroPointFromStar(double starMag, double starPhotonsPerS) noexcept {
  return starMag + 2.5 * std::log10(starPhotonsPerS);
}

double magnitude(double photonsPerS, double zeroPoint) noexcept {
  if (!(photonsPerS > 0.0)) return std::numeric_limits<double>::quiet_NaN();
  return zeroPoint - 2.5 * std::log10(photonsPerS);
}

SegmentScatter segmentScatter(const std::vector<double>& fluxes) noexcept {
  SegmentScatter s;
  s.segments = static_cast<int>(fluxes.size());
  if (fluxes.size() < 2) return s;
  double mean = 0.0;
  for (double f : fluxes)
    mean += f;
  mean /= static_cast<double>(fluxes.size());
  if (!(mean > 0.0)) return s;
  double var = 0.0;
  for (double f : fluxes)
    var += (f - mean) * (f - mean);
  var /= static_cast<double>(fluxes.size() - 1);
  const double k = 2.5 / std::log(10.0);
  s.mean = mean;
  s.sd = std::sqrt(var);
  s.sigmaMean = s.sd / std::sqrt(static_cast<double>(fluxes.size()));
  s.sigmaMagSegment = k * s.sd / mean;
  s.sigmaMag = k * s.sigmaMean / mean;
  return s;
}

}  // namespace st::astro

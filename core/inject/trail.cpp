#include "st/inject/trail.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "st/common/error.hpp"

namespace st::inject {

double Stamp::sum() const {
  double s = 0.0;
  for (const double v : values)
    s += v;
  return s;
}

double stampRadiusPx(const psf::Moffat& psf, double lostFraction, double maxFwhm) {
  const double cap = maxFwhm * psf.fwhm();
  if (!(psf.beta > 1.0)) return cap;
  const double r = psf.radius * std::sqrt(std::pow(lostFraction, 1.0 / (1.0 - psf.beta)) - 1.0);
  return std::min(r, cap);
}

Stamp trailedStamp(const psf::Moffat& psf, double xa, double ya, double xb, double yb, double radiusPx,
                   double maxStepPx) {
  if (!(radiusPx > 0.0) || !(maxStepPx > 0.0))
    throw InputError("trailed stamp: radius and step must be > 0, got " + std::to_string(radiusPx) + " and " +
                     std::to_string(maxStepPx));
  const double length = std::hypot(xb - xa, yb - ya);
  const int steps = std::max(1, static_cast<int>(std::ceil(length / maxStepPx)));
  Stamp s;
  s.x0 = static_cast<int>(std::floor(std::min(xa, xb) - radiusPx));
  s.y0 = static_cast<int>(std::floor(std::min(ya, yb) - radiusPx));
  s.width = static_cast<int>(std::ceil(std::max(xa, xb) + radiusPx)) - s.x0 + 1;
  s.height = static_cast<int>(std::ceil(std::max(ya, yb) + radiusPx)) - s.y0 + 1;
  s.values.assign(static_cast<std::size_t>(s.width) * s.height, 0.0);
  const double r2 = radiusPx * radiusPx;
  for (int k = 0; k < steps; ++k) {
    const double f = (k + 0.5) / steps;
    const double cx = xa + f * (xb - xa), cy = ya + f * (yb - ya);
    const int xLo = static_cast<int>(std::ceil(cx - radiusPx)), xHi = static_cast<int>(std::floor(cx + radiusPx));
    const int yLo = static_cast<int>(std::ceil(cy - radiusPx)), yHi = static_cast<int>(std::floor(cy + radiusPx));
    for (int y = yLo; y <= yHi; ++y)
      for (int x = xLo; x <= xHi; ++x) {
        const double dx = x - cx, dy = y - cy;
        if (dx * dx + dy * dy > r2) continue;
        s.values[static_cast<std::size_t>(y - s.y0) * s.width + (x - s.x0)] += psf.pixelMean(dx, dy);
      }
  }
  const double total = s.sum();
  for (double& v : s.values)
    v /= total;
  return s;
}

double trackInformation(const std::vector<Stamp>& stamps, const std::vector<double>& sigma) {
  if (stamps.size() != sigma.size())
    throw InputError("track information: " + std::to_string(stamps.size()) + " stamps but " +
                     std::to_string(sigma.size()) + " noise values");
  double info = 0.0;
  for (std::size_t n = 0; n < stamps.size(); ++n) {
    if (!(sigma[n] > 0.0))
      throw InputError("track information: the noise of frame " + std::to_string(n) + " is " +
                       std::to_string(sigma[n]) + ", must be > 0");
    double s2 = 0.0;
    for (const double v : stamps[n].values)
      s2 += v * v;
    info += s2 / (sigma[n] * sigma[n]);
  }
  return info;
}

double fluxForSnr(double snr, double information) {
  if (!(information > 0.0)) throw InputError("flux for SNR: the track information must be > 0");
  return snr / std::sqrt(information);
}

}  // namespace st::inject

#include "st/search/sky_motion.hpp"

#include <cmath>
#include <cstdio>

#include "st/common/error.hpp"
#include "st/io/wcs.hpp"

namespace st::search {

SkyMotion skyMotion(const FrameCube& cube, double x, double y, Velocity v) {
  SkyMotion m;
  if (cube.plateScaleArcsecPerPx)
    m.rateDegPerDay = pxPerSecToDegPerDay(v.norm(), *cube.plateScaleArcsecPerPx);
  if (!cube.wcs) return m;
  // Finite difference over tau seconds: small enough to stay local, large enough for double precision.
  constexpr double kTauS = 60.0;
  try {
    const Wcs::Sky a = cube.wcs->pixelToSky(x, y);
    const Wcs::Sky b = cube.wcs->pixelToSky(x + v.vx * kTauS, y + v.vy * kTauS);
    constexpr double kDeg = M_PI / 180.0;
    double dRa = b.raDeg - a.raDeg;
    if (dRa > 180.0) dRa -= 360.0;
    if (dRa < -180.0) dRa += 360.0;
    const double east = dRa * std::cos(0.5 * (a.decDeg + b.decDeg) * kDeg);
    const double north = b.decDeg - a.decDeg;
    m.rateDegPerDay = std::hypot(east, north) / kTauS * kSecondsPerDay;
    if (v.norm() > 0.0) {
      double pa = std::atan2(east, north) / kDeg;
      if (pa < 0.0) pa += 360.0;
      m.paDeg = pa;
    }
  } catch (const InputError&) {
    // No sky position at this pixel: keep the plate-scale rate.
  }
  return m;
}

double staticRateLimitPxS(double fwhmPx, double spanS) {
  return spanS > 0.0 ? fwhmPx / spanS : 0.0;
}

std::string staticRateLimitNote(const FrameCube& cube, double fwhmPx) {
  const double v = staticRateLimitPxS(fwhmPx, cube.timeSpanS());
  char buf[384];
  if (cube.plateScaleArcsecPerPx) {
    std::snprintf(
        buf, sizeof buf,
        "movers slower than %.3g px/s (%.3g deg/day: one PSF FWHM of %.2f px over the %.0f s span) "
        "relative to the stars look static and are removed with them (a track inside the image for part "
        "of the span: one FWHM over the frames that hold it)",
        v, v * *cube.plateScaleArcsecPerPx * 86400.0 / 3600.0, fwhmPx, cube.timeSpanS());
  } else {
    std::snprintf(
        buf, sizeof buf,
        "movers slower than %.3g px/s (one PSF FWHM of %.2f px over the %.0f s span) relative to the "
        "stars look static and are removed with them (a track inside the image for part of the span: one "
        "FWHM over the frames that hold it)",
        v, fwhmPx, cube.timeSpanS());
  }
  return buf;
}

}  // namespace st::search

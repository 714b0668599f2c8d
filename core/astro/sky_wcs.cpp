// The st::Wcs overload of skyMeasurement, in its own translation unit so that code not using a WCS links
// without core/io's wcslib implementation.
#include "st/astro/astrometry.hpp"
#include "st/common/error.hpp"
#include "st/io/wcs.hpp"

namespace st::astro {

SkyMeasurement skyMeasurement(const Wcs& wcs, const fit::FitResult& fit, Velocity skyRate,
                              double mappingEpochOffsetS) {
  return skyMeasurement(
      [&wcs](double x, double y) {
        const Wcs::Sky s = wcs.pixelToSky(x, y);
        return SkyPoint{s.raDeg, s.decDeg};
      },
      fit, skyRate, mappingEpochOffsetS);
}

SkyMeasurement skyMeasurement(const FrameCube& frames, const fit::FitResult& fit, Velocity skyRate) {
  if (!frames.wcs || frames.empty()) throw InputError("sky position: the frames have no WCS");
  const Wcs& wcs = *frames.wcs;
  const FrameInfo& first = frames.info().front();
  const double ox = first.offsetXPx, oy = first.offsetYPx;
  return skyMeasurement(
      [&wcs, ox, oy](double x, double y) {
        const Wcs::Sky s = wcs.pixelToSky(x + ox, y + oy);
        return SkyPoint{s.raDeg, s.decDeg};
      },
      fit, skyRate, frames.timeOffsetsS().front());
}

}  // namespace st::astro

// The st::Wcs overload of skyMeasurement, in its own translation unit so that code not using a WCS links
// without core/io's wcslib implementation.
#include "st/astro/astrometry.hpp"
#include "st/common/error.hpp"
#include "st/io/wcs.hpp"

namespace st::astro {
namespace {

// The WCS's pixel -> sky at pixel (x, y) + (ox, oy).
PixelToSky through(const Wcs& wcs, double ox, double oy) {
  return [&wcs, ox, oy](double x, double y) {
    const Wcs::Sky s = wcs.pixelToSky(x + ox, y + oy);
    return SkyPoint{s.raDeg, s.decDeg};
  };
}

}  // namespace

SkyMeasurement skyMeasurement(const Wcs& wcs, const fit::FitResult& fit, Velocity skyRate,
                              double mappingEpochOffsetS) {
  return skyMeasurement(through(wcs, 0.0, 0.0), fit, skyRate, mappingEpochOffsetS);
}

SkyMeasurement skyMeasurement(const FrameCube& frames, const fit::FitResult& fit, Velocity skyRate) {
  if (!frames.wcs || frames.empty()) throw InputError("sky position: the frames have no WCS");
  const FrameInfo& first = frames.info().front();
  return skyMeasurement(through(*frames.wcs, first.offsetXPx, first.offsetYPx), fit, skyRate,
                        frames.timeOffsetsS().front());
}

}  // namespace st::astro

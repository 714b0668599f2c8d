// The st::Wcs overload of skyMeasurement, in its own translation unit so that code not using a WCS links
// without core/io's wcslib implementation.
#include "st/astro/astrometry.hpp"
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

}  // namespace st::astro

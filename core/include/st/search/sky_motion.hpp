#pragma once
// A candidate's motion on the sky, for reports: rate (deg/day) from the WCS at its position, or from the
// plate scale alone; position angle of the motion (east of north) only when a WCS gives the orientation.
#include <optional>
#include <string>

#include "st/common/frame_cube.hpp"
#include "st/common/units.hpp"

namespace st::search {

struct SkyMotion {
  std::optional<double> rateDegPerDay;  ///< angular rate; empty when neither WCS nor plate scale is known
  std::optional<double> paDeg;          ///< position angle of the motion, degrees east of north, [0, 360)
};

/// Motion of a source at pixel (x, y) moving at v px/s in `cube` (its WCS when present, else its plate
/// scale: rate only). Never throws: a pixel without a sky position gives the plate-scale rate and no PA.
SkyMotion skyMotion(const FrameCube& cube, double x, double y, Velocity v);

/// The slowest motion relative to the stars that pre-processing can tell from a star: one PSF FWHM over the
/// cube's span, px/s. A slower mover looks static in the sky-rate stack: it is masked as a star (or, in a
/// field that does not drift, taken into the per-pixel background) and cannot be found. 0 when the span is 0.
double staticRateLimitPxS(double fwhmPx, double spanS);

/// That limit in words for the search's output, in px/s and, with a plate scale, deg/day.
std::string staticRateLimitNote(const FrameCube& cube, double fwhmPx);

}  // namespace st::search

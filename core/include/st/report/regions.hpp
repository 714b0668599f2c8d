#pragma once
// DS9 region files (DS9 region format version 4.1). With a pixel-to-sky mapping the regions are written in
// the WCS's celestial frame (icrs or fk5: RA/Dec in degrees, radii in arcsec; ds9SkyFrame), so DS9 applies no
// frame change (FK5 J2000 and ICRS differ by up to ~20 mas); without one in image coordinates, converted to
// DS9's 1-based
// pixels here (ARCHITECTURE.md: 1-based at the writer, nowhere else).
#include <optional>
#include <string>
#include <vector>

#include "st/astro/astrometry.hpp"
#include "st/common/units.hpp"

namespace st {
class Wcs;
}

namespace st::report {

struct RegionMark {
  double x = 0.0;  ///< 0-based column at t_ref
  double y = 0.0;  ///< 0-based row at t_ref
  double radiusPx = 5.0;
  std::string text;             ///< label shown by DS9 (quotes and braces are removed)
  std::string color = "green";  ///< a DS9 colour name
  /// When set, a line from the track's position at trackStartS to trackEndS (seconds from t_ref) is added:
  /// in image coordinates the detector track (velocity), on the sky the track relative to the stars
  /// (velocity - skyRate: the sky mapping holds at t_ref, and the field drifts by skyRate).
  std::optional<Velocity> velocity;
  Velocity skyRate;
  double trackStartS = 0.0;
  double trackEndS = 0.0;
};

/// The DS9 name of a WCS's celestial frame from its RADESYS (FITS WCS paper II: without RADESYS, FK5 when
/// EQUINOX >= 1984, FK4 before, ICRS without EQUINOX): "icrs", "fk5", "fk4", or "fk5" for others.
[[nodiscard]] std::string ds9SkyFrame(const Wcs& wcs);

/// The region file text. `toSky` (may be empty) maps 0-based pixels at t_ref to the WCS's sky (see
/// skyMappingAtTRef); with it, coordinates are `skyFrame` (ds9SkyFrame) degrees and radii arcsec from the
/// local scale.
[[nodiscard]] std::string ds9Regions(const std::vector<RegionMark>& marks, const astro::PixelToSky& toSky,
                                     const std::string& skyFrame = "fk5");

/// Writes ds9Regions to `path`. Throws st::InputError naming the path.
void writeDs9Regions(const std::string& path, const std::vector<RegionMark>& marks,
                     const astro::PixelToSky& toSky, const std::string& skyFrame = "fk5");

/// The mapping of pixels at t_ref through a WCS that belongs to the frame at `mappingEpochOffsetS` (seconds
/// from t_ref; the first frame's for a cube's FITS WCS), whose registration offset is `mappingFrameOffset`
/// (FrameInfo::offsetXPx/offsetYPx; dithers): a point at (x, y) at t_ref was at (x, y) + skyRate *
/// mappingEpochOffsetS + that offset in that frame (the stars drift at skyRate), the convention of
/// astro::skyMeasurement.
[[nodiscard]] astro::PixelToSky skyMappingAtTRef(const Wcs& wcs, Velocity skyRate, double mappingEpochOffsetS,
                                                 PixelOffset mappingFrameOffset = {});
/// The same through the WCS of `frames` (which it must have), the first frame's: at its epoch and its
/// registration offset.
[[nodiscard]] astro::PixelToSky skyMappingAtTRef(const FrameCube& frames, Velocity skyRate);

}  // namespace st::report

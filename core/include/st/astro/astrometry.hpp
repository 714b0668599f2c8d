#pragma once
// Astrometry from co-moving fits (paper §5.1-5.2): static stars are fitted the same way as the asteroid,
// at the sky rate, and the asteroid is given relative to them; with a WCS, its RA/Dec (ICRS, degrees) at
// t_ref, its rate (deg/day, arcsec/min) and position angle (east of north); without one, the rate from a
// plate scale the user gives.
#include <functional>
#include <optional>
#include <vector>

#include "st/common/frame_cube.hpp"
#include "st/common/units.hpp"
#include "st/fit/comoving_fit.hpp"

namespace st {
class Wcs;
}

namespace st::astro {

/// Fits a static star near (x, y) at t_ref with the velocity held at `skyRate` (px/s; zero for a tracked
/// telescope): fitComoving with FitOptions::fixVelocity.
[[nodiscard]] fit::FitResult fitStar(const FrameCube& cube, double x, double y, Velocity skyRate,
                                     fit::FitOptions options);

/// The asteroid relative to one star, at the common reference time, pixels (asteroid - star).
struct RelativeOffset {
  double dx = 0.0, dy = 0.0;
  double sigmaX = 0.0, sigmaY = 0.0;  ///< both fits' noise-model errors in quadrature
};
struct RelativeAstrometry {
  std::vector<RelativeOffset> perStar;  ///< one per converged star fit, in the order given
  /// The asteroid's position implied by the stars: mean over stars of (star position + offset) weighted by
  /// 1/sigma^2 — with one frame of reference this is the asteroid's own position; across epochs (the
  /// paper's two scans) the per-star offsets are what cancels pointing and atmosphere.
  double x = 0.0, y = 0.0;
  double sigmaX = 0.0, sigmaY = 0.0;
  int starsUsed = 0;
};
/// Throws st::InputError when the asteroid fit has not converged or no star fit has, or when the fits do
/// not share a reference time.
[[nodiscard]] RelativeAstrometry relativeToStars(const fit::FitResult& asteroid,
                                                 const std::vector<fit::FitResult>& stars);

struct SkyPoint {
  double raDeg = 0.0;
  double decDeg = 0.0;
};
/// Any 0-based pixel -> ICRS mapping (a Wcs, or a test projection).
using PixelToSky = std::function<SkyPoint(double x, double y)>;

struct SkyMeasurement {
  double tRefMjd = 0.0;
  double raDeg = 0.0, decDeg = 0.0;  ///< at t_ref
  double sigmaRaArcsec = 0.0;        ///< along RA (times cos Dec), from sigma_x, sigma_y and the local scale
  double sigmaDecArcsec = 0.0;
  double rateDegPerDay = 0.0;  ///< on-sky rate relative to the stars
  double rateArcsecPerMin = 0.0;
  double positionAngleDeg = 0.0;    ///< direction of motion, east of north, [0, 360)
  double sigmaRateDegPerDay = 0.0;  ///< from the fit's velocity errors
};

/// Sky position and motion of a fitted object. The mapping belongs to the frame at `mappingEpochOffsetS`
/// (seconds from the cube's t_ref; the first frame's for a FITS WCS): the stars moved by skyRate since
/// then, so the object's position at t_ref is mapped at (x, y) - skyRate * (0 - mappingEpochOffsetS), and
/// its motion on the sky is its velocity relative to the stars, v - skyRate. Local derivatives of the
/// mapping are taken by central differences over +-0.5 px.
[[nodiscard]] SkyMeasurement skyMeasurement(const PixelToSky& pixelToSky, const fit::FitResult& fit,
                                            Velocity skyRate, double mappingEpochOffsetS);
/// The same through a FITS WCS (st::Wcs, implemented in core/io).
[[nodiscard]] SkyMeasurement skyMeasurement(const Wcs& wcs, const fit::FitResult& fit, Velocity skyRate,
                                            double mappingEpochOffsetS);
/// The same through the WCS of `frames`, the first frame's (a FITS WCS belongs to it): its epoch, and its
/// registration offset (FrameInfo::offsetXPx/offsetYPx): the registration puts frame n's star field that far
/// from the linear sky-rate model, so a fitted position (x, y) lies at (x, y) + the first frame's offset in
/// that frame's own pixels, which its WCS maps. Dithered or guided-drift frames have a non-zero one.
/// Throws st::InputError when the frames have no WCS.
[[nodiscard]] SkyMeasurement skyMeasurement(const FrameCube& frames, const fit::FitResult& fit,
                                            Velocity skyRate);

/// The on-sky motion of a velocity `relativePxPerS` (relative to the stars) at pixel (x, y) of a mapping,
/// as skyMeasurement gives it: rate and position angle (east of north) through the mapping's local
/// derivatives (central differences over +-0.5 px).
struct SkyMotion {
  double rateDegPerDay = 0.0;
  double rateArcsecPerMin = 0.0;
  double positionAngleDeg = 0.0;  ///< [0, 360); 0 when the rate is 0
};
[[nodiscard]] SkyMotion skyMotionAt(const PixelToSky& pixelToSky, double x, double y, Velocity relativePxPerS);

/// Rate without a WCS, from a plate scale (arcsec/px): |v - skyRate| in deg/day and arcsec/min. The
/// position angle needs the orientation, which only a WCS gives.
struct PlateScaleRate {
  double rateDegPerDay = 0.0;
  double rateArcsecPerMin = 0.0;
  double sigmaRateDegPerDay = 0.0;
};
[[nodiscard]] PlateScaleRate rateFromPlateScale(const fit::FitResult& fit, Velocity skyRate,
                                                double arcsecPerPx);

}  // namespace st::astro

#pragma once
// The GUI's one velocity convention (issue 18 §6): a motion is shown relative to the stars (the velocity
// minus the sky rate, as in the paper and the reports' rate_deg_day / pa_deg), as components, rate and
// position angle, in the unit chosen in the Search dock (px/s when the cube has no plate scale). The
// candidates table, the velocity map's axes and readout, the candidate inspector's header, the fit table
// and the figure captions all call these functions; none converts on its own.
#include <QString>
#include <optional>

#include "observation.hpp"

namespace st::ui {

struct MotionVsSky {
  double vx = 0.0;    ///< x component of (v - sky rate), in `unit`
  double vy = 0.0;    ///< y component, in `unit`
  double rate = 0.0;  ///< |v - sky rate|, in `unit`
  std::optional<double> paDeg;  ///< direction of that motion, degrees east of north; needs a WCS
  VelocityUnit unit = VelocityUnit::PxPerS;  ///< the unit of vx, vy and rate as shown
};

/// The unit motions are shown in: the Search dock's, or px/s without a plate scale.
[[nodiscard]] VelocityUnit shownUnit(const Observation& obs);
/// A velocity (px/s, as searched) relative to the sky rate, in shownUnit(): components only (no WCS call),
/// for axes and markers.
[[nodiscard]] Velocity toShownVsSky(const Observation& obs, Velocity v);
/// The inverse of toShownVsSky: a point of the velocity map's axes back to px/s.
[[nodiscard]] Velocity fromShownVsSky(const Observation& obs, Velocity shown);
/// The motion of a source at pixel (x, y) moving at v px/s: components and rate (toShownVsSky) and the
/// position angle through the cube's WCS at (x, y) (search::skyMotion).
[[nodiscard]] MotionVsSky motionVsSky(const Observation& obs, double x, double y, Velocity v);
/// "rate 12.3 deg/day vs sky, PA 245.1°" (4 significant digits; PA only with a WCS).
[[nodiscard]] QString describeMotion(const MotionVsSky& m);
/// The same with the components: "rate 12.3 deg/day vs sky, PA 245.1° (vx -5.2, vy 11.1)".
[[nodiscard]] QString describeMotionWithComponents(const MotionVsSky& m);

/// A candidate as the captions describe it: its accepted co-moving fit when that converged (its position,
/// velocity and SNR supersede the search cell's), else its search cell.
struct ShownTrack {
  double x = 0.0, y = 0.0;
  Velocity v;
  double snr = 0.0;
  bool fitted = false;
};
[[nodiscard]] ShownTrack shownTrack(const Observation& obs, int index, const search::Candidate& c);
/// "fit SNR 15.9, rate 6.005 deg/day vs sky, PA 60.2°" (or "search SNR ..." without an accepted fit).
[[nodiscard]] QString describeShownTrack(const Observation& obs, const ShownTrack& t);

}  // namespace st::ui

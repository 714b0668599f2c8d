#pragma once
// Velocity units shown in the GUI: px/s always; arcsec/min and deg/day when a plate scale is known
// (conversions from st/common/units.hpp).
#include <QString>
#include <optional>

#include "st/common/units.hpp"

namespace st::ui {

enum class VelocityUnit { PxPerS, ArcsecPerMin, DegPerDay };

QString unitLabel(VelocityUnit unit);
/// px/s -> the unit (needs a plate scale for angular units; without one, returns px/s unchanged).
double fromPxPerS(double pxPerS, VelocityUnit unit, std::optional<double> arcsecPerPx);
/// The unit -> px/s.
double toPxPerS(double value, VelocityUnit unit, std::optional<double> arcsecPerPx);

}  // namespace st::ui

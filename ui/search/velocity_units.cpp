#include "velocity_units.hpp"

namespace st::ui {

QString unitLabel(VelocityUnit unit) {
  switch (unit) {
    case VelocityUnit::ArcsecPerMin:
      return QStringLiteral("\"/min");
    case VelocityUnit::DegPerDay:
      return QStringLiteral("deg/day");
    case VelocityUnit::PxPerS:
      break;
  }
  return QStringLiteral("px/s");
}

double fromPxPerS(double pxPerS, VelocityUnit unit, std::optional<double> arcsecPerPx) {
  if (!arcsecPerPx) return pxPerS;
  switch (unit) {
    case VelocityUnit::ArcsecPerMin:
      return pxPerSecToArcsecPerMin(pxPerS, *arcsecPerPx);
    case VelocityUnit::DegPerDay:
      return pxPerSecToDegPerDay(pxPerS, *arcsecPerPx);
    case VelocityUnit::PxPerS:
      break;
  }
  return pxPerS;
}

double toPxPerS(double value, VelocityUnit unit, std::optional<double> arcsecPerPx) {
  if (!arcsecPerPx) return value;
  switch (unit) {
    case VelocityUnit::ArcsecPerMin:
      return arcsecPerMinToPxPerSec(value, *arcsecPerPx);
    case VelocityUnit::DegPerDay:
      return degPerDayToPxPerSec(value, *arcsecPerPx);
    case VelocityUnit::PxPerS:
      break;
  }
  return value;
}

}  // namespace st::ui

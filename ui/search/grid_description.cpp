#include "grid_description.hpp"

#include <algorithm>

namespace st::ui {

QString gridDescription(const search::VelocityGrid& grid, VelocityUnit unit,
                        std::optional<double> arcsecPerPx, double timeSpanS) {
  QString text = QString("%1 × %2 = %3 velocities").arg(grid.nvx).arg(grid.nvy).arg(grid.count());
  if (!(grid.stepPxS > 0.0)) return text;
  const VelocityUnit shown = arcsecPerPx ? unit : VelocityUnit::PxPerS;
  const double halfPxS = 0.5 * (std::max(grid.nvx, grid.nvy) - 1) * grid.stepPxS;
  auto speed = [&](double pxS) {
    return QString("%1 %2").arg(fromPxPerS(pxS, shown, arcsecPerPx), 0, 'g', 3).arg(unitLabel(shown));
  };
  text += "\n±" + speed(halfPxS);
  if (shown != VelocityUnit::PxPerS) text += QString(" (±%1 px/s)").arg(halfPxS, 0, 'g', 3);
  text += " in steps of " + speed(grid.stepPxS);
  if (timeSpanS > 0.0)
    text += QString(" = %1 px over the %2 s span")
                .arg(grid.stepPxS * timeSpanS, 0, 'f', 2)
                .arg(timeSpanS, 0, 'f', 1);
  return text;
}

}  // namespace st::ui

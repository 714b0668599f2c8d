#include "figure_preset.hpp"

#include <QRect>
#include <algorithm>
#include <cmath>
#include <string>

#include "st/common/error.hpp"
#include "st/common/units.hpp"
#include "st/stack/ipsa.hpp"

namespace st::ui {
namespace {

QString pxRate(Velocity v) {
  return QString("(%1, %2) px/s").arg(v.vx, 0, 'f', 3).arg(v.vy, 0, 'f', 3);
}

ImagePanel stampPanel(const Image& full, const QRect& rect, const SkyAndObjectOptions& o,
                      const QString& title) {
  ImagePanel p;
  p.image = std::make_shared<const Image>(cropImage(full, rect));
  p.origin = QPointF(rect.x(), rect.y());
  p.display = o.display;
  p.title = title;
  p.units = o.units;
  p.plateScaleArcsecPerPx = o.plateScaleArcsecPerPx;
  p.compass = o.compass;
  return p;
}

}  // namespace

ImageFigure skyAndObjectFigure(const search::FilteredCube& cube, const search::Candidate& c, Velocity skyRate,
                               const SkyAndObjectOptions& options) {
  const FrameCube& frames = cube.frames;
  if (frames.empty()) throw InputError("figure: the cube has no frames");
  if (c.x < 0 || c.y < 0 || c.x >= frames.width() || c.y >= frames.height())
    throw InputError("figure: candidate at (" + std::to_string(c.x) + ", " + std::to_string(c.y) +
                     ") is outside the frame");
  const auto dt = frames.timeOffsetsS();
  const stack::StackResult object = stack::stackIpsa(frames, dt, c.v);
  const stack::StackResult sky = stack::stackIpsa(frames, dt, skyRate);
  const int h = std::max(options.halfSizePx, 4);
  const QRect rect =
      QRect(c.x - h, c.y - h, 2 * h + 1, 2 * h + 1).intersected(QRect(0, 0, frames.width(), frames.height()));

  ImageFigure fig;
  fig.panels.push_back(stampPanel(object.sum, rect, options, "tracking the object"));
  fig.panels.push_back(stampPanel(sky.sum, rect, options, "tracking the stars"));
  const Image& stamp = *fig.panels[0].image;
  const auto [lo, hi] = computeLimits(stamp.data(), stamp.size(), options.display);
  for (auto& p : fig.panels) {
    p.lo = lo;
    p.hi = hi;
  }
  const double fwhm = cube.psfFwhmPx > 0 ? cube.psfFwhmPx : 3.0;
  const QPointF at(c.x - rect.x(), c.y - rect.y());
  fig.panels[0].arrows.push_back(
      {at + QPointF(0, 1.5 * fwhm + 8), at + QPointF(0, 1.5 * fwhm + 1), QColor(255, 200, 0), {}});

  const Velocity rel{c.v.vx - skyRate.vx, c.v.vy - skyRate.vy};
  const auto [first, last] = std::minmax_element(dt.begin(), dt.end());
  const QPointF start = at + QPointF(rel.vx * *first, rel.vy * *first);
  const QPointF end = at + QPointF(rel.vx * *last, rel.vy * *last);
  const double len = std::hypot(end.x() - start.x(), end.y() - start.y());
  const QPointF side = len > 0 ? QPointF(-(end.y() - start.y()), end.x() - start.x()) / len : QPointF(0, 1);
  const QPointF offset = side * (2 * fwhm + 2);
  fig.panels[1].arrows.push_back({start + offset, end + offset, QColor(255, 200, 0), "motion"});

  fig.title = QString("Synthetic tracking of candidate #%1 (%2 %3)")
                  .arg(options.candidateNumber)
                  .arg(options.snrLabel)
                  .arg(c.snr, 0, 'f', 1);
  QString onSky = options.motion.isEmpty() ? QString() : ", " + options.motion;
  if (onSky.isEmpty() && options.plateScaleArcsecPerPx && *options.plateScaleArcsecPerPx > 0)
    onSky =
        QString(", %1 deg/day on the sky")
            .arg(pxPerSecToDegPerDay(std::hypot(rel.vx, rel.vy), *options.plateScaleArcsecPerPx), 0, 'f', 2);
  fig.caption = QString(
                    "IPSA stacks of %1 frames over %2 s. Left: tracking the object at v = %3%4 (arrow). "
                    "Right: tracking the stars at %5; the object streaks along the arrow and its surface "
                    "brightness drops.")
                    .arg(frames.frameCount())
                    .arg(frames.timeSpanS(), 0, 'f', 1)
                    .arg(pxRate(c.v), onSky, pxRate(skyRate));
  return fig;
}

}  // namespace st::ui

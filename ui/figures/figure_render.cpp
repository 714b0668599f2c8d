#include "figure_render.hpp"

#include <QFontMetricsF>
#include <QPainter>
#include <QPainterPath>
#include <algorithm>
#include <array>
#include <cmath>

namespace st::ui {
namespace {

// Layout of a panel, in points.
constexpr double kTitleH = 16.0;
constexpr double kTitleLineH = 11.0;  // each further line of a panel title
constexpr double kAxisLeft = 34.0;
constexpr double kAxisBottom = 26.0;
constexpr double kBarGap = 6.0;
constexpr double kBarW = 9.0;
constexpr double kBarLabels = 46.0;  // tick labels and the units, right of the bar
constexpr double kPanelGap = 10.0;
constexpr double kFigTitleH = 20.0;
constexpr double kCaptionH = 30.0;

QFont figureFont(int pixelSize, bool bold = false) {
  QFont f("DejaVu Sans");
  f.setPixelSize(pixelSize);
  f.setBold(bold);
  return f;
}

double leftMargin(const ImagePanel& p) {
  return p.showAxes ? kAxisLeft : 2.0;
}
double rightMargin(const ImagePanel& p) {
  return p.showColourBar ? kBarGap + kBarW + kBarLabels : 2.0;
}
double bottomMargin(const ImagePanel& p) {
  return p.showAxes ? kAxisBottom : 2.0;
}
double topMargin(const ImagePanel& p) {
  return p.title.isEmpty() ? 4.0 : kTitleH + kTitleLineH * static_cast<double>(p.title.count('\n'));
}

// Columns and rows of the grid the panels are laid out in.
std::pair<int, int> gridOf(const ImageFigure& figure) {
  const int n = std::max(static_cast<int>(figure.panels.size()), 1);
  const int cols = figure.columns > 0 ? std::min(figure.columns, n) : n;
  return {cols, (n + cols - 1) / cols};
}

QString tickText(double v) {
  // Whole numbers as such (10000, not 1e+04) up to a million; the rest with 4 significant digits.
  if (std::abs(v) < 1e6 && std::abs(v - std::round(v)) < 1e-9 * std::max(1.0, std::abs(v)))
    return QString::number(static_cast<long long>(std::llround(v)));
  return QString::number(v, 'g', 4);
}

// Height of the caption block for a figure `width` wide: the wrapped text plus a margin.
double captionHeight(const ImageFigure& figure, double width) {
  if (figure.caption.isEmpty()) return 0.0;
  const QFontMetricsF fm(figureFont(8));
  const QRectF r =
      fm.boundingRect(QRectF(0, 0, width - 12, 1000), Qt::AlignLeft | Qt::TextWordWrap, figure.caption);
  return std::max(kCaptionH, r.height() + 8);
}

void drawArrow(QPainter& painter, QPointF from, QPointF to, double head) {
  painter.drawLine(from, to);
  const QPointF d = to - from;
  const double len = std::hypot(d.x(), d.y());
  if (len <= 0) return;
  const QPointF u = d / len;
  const QPointF n(-u.y(), u.x());
  QPainterPath tip;
  tip.moveTo(to);
  tip.lineTo(to - u * head + n * head * 0.45);
  tip.lineTo(to - u * head - n * head * 0.45);
  tip.closeSubpath();
  painter.fillPath(tip, painter.pen().color());
}

// Maps image pixels (0-based, y up, centres at integers) into the drawn image rectangle.
struct PixelMap {
  QRectF rect;
  double sx = 1.0;
  double sy = 1.0;
  [[nodiscard]] QPointF map(QPointF p) const {
    return {rect.left() + (p.x() + 0.5) * sx, rect.bottom() - (p.y() + 0.5) * sy};
  }
};

void drawAxes(QPainter& painter, const ImagePanel& p, const PixelMap& m) {
  const Image& img = *p.image;
  painter.setPen(QPen(Qt::black, 0.6));
  painter.setBrush(Qt::NoBrush);
  painter.drawRect(m.rect);
  painter.setFont(figureFont(7));
  for (double t : niceTicks(p.origin.x() - 0.5, p.origin.x() + img.width - 0.5, 5)) {
    const double x = m.map({t - p.origin.x(), 0}).x();
    painter.drawLine(QPointF(x, m.rect.bottom()), QPointF(x, m.rect.bottom() + 3));
    painter.drawText(QRectF(x - 20, m.rect.bottom() + 3, 40, 10), Qt::AlignHCenter | Qt::AlignTop,
                     tickText(t));
  }
  for (double t : niceTicks(p.origin.y() - 0.5, p.origin.y() + img.height - 0.5, 5)) {
    const double y = m.map({0, t - p.origin.y()}).y();
    painter.drawLine(QPointF(m.rect.left() - 3, y), QPointF(m.rect.left(), y));
    painter.drawText(QRectF(m.rect.left() - 34, y - 5, 30, 10), Qt::AlignRight | Qt::AlignVCenter,
                     tickText(t));
  }
  painter.setFont(figureFont(8));
  painter.drawText(QRectF(m.rect.left(), m.rect.bottom() + 13, m.rect.width(), 12), Qt::AlignHCenter,
                   p.xLabel);
  painter.save();
  painter.translate(m.rect.left() - 33, m.rect.center().y());
  painter.rotate(-90);
  // Rotated by -90 degrees: the text's vertical extent [0, 11] becomes [left - 33, left - 22] on the page.
  painter.drawText(QRectF(-m.rect.height() / 2, 0, m.rect.height(), 11), Qt::AlignHCenter | Qt::AlignTop,
                   p.yLabel);
  painter.restore();
}

void drawColourBar(QPainter& painter, const ImagePanel& p, const QRectF& imageRect) {
  const QRectF bar(imageRect.right() + kBarGap, imageRect.top(), kBarW, imageRect.height());
  const auto& table = colormapTable(p.display.colormap);
  QImage strip(1, 256, QImage::Format_RGB32);
  for (int i = 0; i < 256; ++i) {
    const double v = p.lo + (p.hi - p.lo) * i / 255.0;
    const double t = stretchValue(v, p.lo, p.hi, p.display.stretch);
    strip.setPixel(0, 255 - i, table[static_cast<std::size_t>(std::clamp(std::lround(t * 255.0), 0L, 255L))]);
  }
  painter.drawImage(bar, strip);
  painter.setPen(QPen(Qt::black, 0.6));
  painter.setBrush(Qt::NoBrush);
  painter.drawRect(bar);
  painter.setFont(figureFont(7));
  for (double t : niceTicks(p.lo, p.hi, 5)) {
    const double y = bar.bottom() - (t - p.lo) / (p.hi - p.lo) * bar.height();
    painter.drawLine(QPointF(bar.right(), y), QPointF(bar.right() + 3, y));
    painter.drawText(QRectF(bar.right() + 4, y - 5, 30, 10), Qt::AlignLeft | Qt::AlignVCenter, tickText(t));
  }
  painter.save();
  painter.translate(bar.right() + kBarLabels - 4, bar.center().y());
  painter.rotate(-90);
  painter.setFont(figureFont(8));
  painter.drawText(QRectF(-bar.height() / 2, -11, bar.height(), 11), Qt::AlignHCenter | Qt::AlignBottom,
                   p.units);
  painter.restore();
}

// White line with a dark outline, readable on any image.
void outlinedLine(QPainter& painter, QPointF a, QPointF b) {
  painter.setPen(QPen(QColor(0, 0, 0, 200), 3.0, Qt::SolidLine, Qt::FlatCap));
  painter.drawLine(a, b);
  painter.setPen(QPen(Qt::white, 1.4, Qt::SolidLine, Qt::FlatCap));
  painter.drawLine(a, b);
}

void drawScaleBar(QPainter& painter, const ImagePanel& p, const PixelMap& m) {
  const double arcsec = scaleBarArcsec(*p.plateScaleArcsecPerPx, p.image->width);
  if (arcsec <= 0) return;
  const double len = arcsec / *p.plateScaleArcsecPerPx * m.sx;
  const QPointF a(m.rect.left() + 8, m.rect.bottom() - 8);
  outlinedLine(painter, a, a + QPointF(len, 0));
  painter.setFont(figureFont(8, true));
  painter.setPen(Qt::white);
  painter.drawText(QRectF(a.x() - 10, a.y() - 15, len + 20, 12), Qt::AlignHCenter | Qt::AlignBottom,
                   scaleBarText(arcsec));
}

void drawCompass(QPainter& painter, const Compass& c, const QRectF& rect) {
  const double len = std::min(22.0, rect.width() * 0.18);
  const QPointF o(rect.right() - len - 10, rect.top() + len + 10);
  painter.setFont(figureFont(8, true));
  for (const auto& [dir, text] : {std::pair{c.north, QString("N")}, std::pair{c.east, QString("E")}}) {
    const QPointF d(dir.x(), -dir.y());  // y up in the image, down on the page
    painter.setPen(QPen(Qt::white, 1.2));
    drawArrow(painter, o, o + d * len, 4.0);
    painter.drawText(QRectF(o.x() + d.x() * (len + 7) - 6, o.y() + d.y() * (len + 7) - 6, 12, 12),
                     Qt::AlignCenter, text);
  }
}

void drawOverlays(QPainter& painter, const ImagePanel& p, const PixelMap& m) {
  painter.save();
  painter.setClipRect(m.rect);
  painter.setFont(figureFont(8));
  for (const auto& mk : p.markers) {
    painter.setPen(QPen(mk.colour, 1.0));
    painter.setBrush(Qt::NoBrush);
    const QPointF c = m.map(mk.pixel);
    painter.drawEllipse(c, mk.radiusPx * m.sx, mk.radiusPx * m.sy);
    if (!mk.label.isEmpty()) painter.drawText(c + QPointF(mk.radiusPx * m.sx + 2, -2), mk.label);
  }
  for (const auto& a : p.arrows) {
    painter.setPen(QPen(a.colour, 1.5));
    drawArrow(painter, m.map(a.from), m.map(a.to), 6.0);
    if (!a.label.isEmpty()) painter.drawText(m.map(a.from) + QPointF(3, 10), a.label);
  }
  if (p.showScaleBar && p.plateScaleArcsecPerPx && *p.plateScaleArcsecPerPx > 0) drawScaleBar(painter, p, m);
  if (p.showCompass && p.compass) drawCompass(painter, *p.compass, m.rect);
  painter.restore();
}

void paintPanel(QPainter& painter, const QRectF& area, const ImagePanel& p) {
  if (!p.image || p.image->empty()) return;
  const Image& img = *p.image;
  const double availW = area.width() - leftMargin(p) - rightMargin(p);
  const double availH = area.height() - topMargin(p) - bottomMargin(p);
  const double scale = std::min(availW / img.width, availH / img.height);
  const QSizeF drawn(img.width * scale, img.height * scale);
  const double left = area.left() + leftMargin(p) + (availW - drawn.width()) / 2;
  const QRectF rect(left, area.top() + topMargin(p), drawn.width(), drawn.height());
  if (!p.title.isEmpty()) {
    painter.setPen(Qt::black);
    // The first line bold, further lines (a sheet's rate and direction) smaller, each centred on the image.
    const QStringList lines = p.title.split('\n');
    for (int k = 0; k < lines.size(); ++k) {
      painter.setFont(k == 0 ? figureFont(9, true) : figureFont(8));
      const double y = area.top() + (k == 0 ? 0.0 : kTitleH - 3 + kTitleLineH * (k - 1));
      painter.drawText(QRectF(rect.left() - kPanelGap / 2 - leftMargin(p) / 2, y,
                              rect.width() + kPanelGap + leftMargin(p) / 2 + rightMargin(p) / 2,
                              k == 0 ? kTitleH - 3 : kTitleLineH),
                       Qt::AlignHCenter | Qt::AlignVCenter | Qt::TextDontClip, lines[k]);
    }
  }
  painter.drawImage(rect, renderImage(img, p.lo, p.hi, p.display));
  const PixelMap map{rect, scale, scale};
  drawOverlays(painter, p, map);
  if (p.showAxes) drawAxes(painter, p, map);
  if (p.showColourBar) drawColourBar(painter, p, rect);
}

}  // namespace

QSizeF naturalFigureSize(const ImageFigure& figure, double widthPt) {
  const auto [cols, rows] = gridOf(figure);
  const double panelW = (widthPt - kPanelGap * (cols - 1)) / cols;
  double panelH = 0.0;
  for (const auto& p : figure.panels) {
    if (!p.image || p.image->empty()) continue;
    const double w = panelW - leftMargin(p) - rightMargin(p);
    panelH = std::max(panelH, w * p.image->height / p.image->width + topMargin(p) + bottomMargin(p));
  }
  const double h = panelH * rows + kPanelGap * (rows - 1) + (figure.title.isEmpty() ? 0 : kFigTitleH) +
                   captionHeight(figure, widthPt);
  return {widthPt, std::ceil(std::max(h, 40.0))};
}

void paintImageFigure(QPainter& painter, const QSizeF& size, const ImageFigure& figure) {
  painter.save();
  painter.setRenderHint(QPainter::Antialiasing, true);
  painter.setRenderHint(QPainter::TextAntialiasing, true);
  painter.setRenderHint(QPainter::SmoothPixmapTransform, false);  // image pixels stay square
  painter.fillRect(QRectF(QPointF(0, 0), size), Qt::white);
  double top = 0.0;
  double bottom = size.height();
  if (!figure.title.isEmpty()) {
    painter.setPen(Qt::black);
    painter.setFont(figureFont(11, true));
    painter.drawText(QRectF(0, 2, size.width(), kFigTitleH - 4), Qt::AlignCenter, figure.title);
    top = kFigTitleH;
  }
  if (!figure.caption.isEmpty()) {
    const double capH = captionHeight(figure, size.width());
    bottom -= capH;
    painter.setPen(Qt::black);
    painter.setFont(figureFont(8));
    painter.drawText(QRectF(6, bottom + 2, size.width() - 12, capH - 4),
                     Qt::AlignLeft | Qt::AlignTop | Qt::TextWordWrap, figure.caption);
  }
  const auto [cols, rows] = gridOf(figure);
  const double panelW = (size.width() - kPanelGap * (cols - 1)) / cols;
  const double panelH = (bottom - top - kPanelGap * (rows - 1)) / rows;
  for (std::size_t i = 0; i < figure.panels.size(); ++i) {
    const auto col = static_cast<double>(static_cast<int>(i) % cols);
    const auto row = static_cast<double>(static_cast<int>(i) / cols);
    paintPanel(painter, QRectF(col * (panelW + kPanelGap), top + row * (panelH + kPanelGap), panelW, panelH),
               figure.panels[i]);
  }
  painter.restore();
}

double scaleBarArcsec(double arcsecPerPx, double widthPx) {
  if (!(arcsecPerPx > 0) || !(widthPx > 0)) return 0.0;
  const double maxLen = 0.25 * widthPx * arcsecPerPx;
  static constexpr std::array<double, 7> kLong = {30, 60, 120, 300, 600, 1800, 3600};
  double best = 0.0;
  for (int k = -2; k <= 1; ++k)
    for (double m : {1.0, 2.0, 5.0}) {
      const double v = m * std::pow(10.0, k);
      if (v <= maxLen) best = std::max(best, v);
    }
  for (double v : kLong)
    if (v <= maxLen) best = std::max(best, v);
  return best;
}

QString scaleBarText(double arcsec) {
  if (arcsec >= 3600) return QString("%1°").arg(arcsec / 3600.0, 0, 'g', 3);
  if (arcsec >= 60) return QString("%1'").arg(arcsec / 60.0, 0, 'g', 3);
  return QString("%1\"").arg(arcsec, 0, 'g', 3);
}

std::vector<double> niceTicks(double lo, double hi, int target) {
  std::vector<double> ticks;
  if (!(hi > lo) || target < 1 || !std::isfinite(lo) || !std::isfinite(hi)) return ticks;
  const double raw = (hi - lo) / target;
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  double step = mag;
  for (double m : {1.0, 2.0, 5.0, 10.0})
    if (m * mag >= raw) {
      step = m * mag;
      break;
    }
  for (double t = std::ceil(lo / step) * step; t <= hi + 1e-9 * step; t += step)
    ticks.push_back(std::abs(t) < 1e-12 * step ? 0.0 : t);
  return ticks;
}

std::optional<Compass> compassAt(const SkyOfPixel& sky, double x, double y) {
  if (!sky) return std::nullopt;
  try {
    const auto c = sky(x, y);
    const auto px = sky(x + 1, y);
    const auto py = sky(x, y + 1);
    if (!c || !px || !py) return std::nullopt;
    const double cosDec = std::cos(c->second * M_PI / 180.0);
    auto dRa = [](double a, double b) { return std::remainder(a - b, 360.0); };
    // J = [[dA/dx, dA/dy], [dD/dx, dD/dy]], A = RA cos Dec, D = Dec (degrees).
    const double a = dRa(px->first, c->first) * cosDec, b = dRa(py->first, c->first) * cosDec;
    const double cc = px->second - c->second, d = py->second - c->second;
    const double det = a * d - b * cc;
    if (!(std::abs(det) > 0) || !std::isfinite(det)) return std::nullopt;
    // J^-1 = [[d, -b], [-cc, a]] / det.
    auto unit = [](QPointF v) { return v / std::hypot(v.x(), v.y()); };
    const QPointF north = unit(QPointF(-b, a) / det);
    const QPointF east = unit(QPointF(d, -cc) / det);
    return Compass{north, east};
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

Image cropImage(const Image& image, const QRect& rect) {
  const QRect r = rect.intersected(QRect(0, 0, image.width, image.height));
  if (r.isEmpty()) return {};
  Image out(r.width(), r.height());
  for (int y = 0; y < r.height(); ++y)
    std::copy_n(image.data() + static_cast<std::size_t>(y + r.y()) * image.width + r.x(), r.width(),
                out.data() + static_cast<std::size_t>(y) * r.width());
  return out;
}

}  // namespace st::ui

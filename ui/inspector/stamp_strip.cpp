#include "stamp_strip.hpp"

#include <QPaintEvent>
#include <QPainter>
#include <algorithm>

namespace st::ui {

std::pair<double, double> commonLimits(const std::vector<const Image*>& images,
                                       const DisplaySettings& settings) {
  std::vector<float> pooled;
  // A bounded sample: every k-th pixel when the images are large (a movie of many frames).
  std::size_t total = 0;
  for (const Image* im : images)
    if (im) total += im->size();
  const std::size_t step = std::max<std::size_t>(1, total / 200000);
  pooled.reserve(total / step + 1);
  std::size_t k = 0;
  for (const Image* im : images) {
    if (!im) continue;
    for (float p : im->pixels)
      if (k++ % step == 0) pooled.push_back(p);
  }
  if (pooled.empty()) return {0.0, 1.0};
  return computeLimits(pooled.data(), pooled.size(), settings);
}

StampStrip::StampStrip(QWidget* parent) : QWidget(parent) {
  m_settings.limits = LimitsMode::Percentile;
  m_settings.percentile = 99.5;
  m_settings.colormap = Colormap::Inferno;
  setMinimumHeight(90);
  setSizePolicy(QSizePolicy::Expanding, QSizePolicy::Preferred);
}

void StampStrip::setTiles(std::vector<Tile> tiles) {
  m_tiles = std::move(tiles);
  rerender();
}

void StampStrip::clear() {
  m_tiles.clear();
  m_rendered.clear();
  update();
}

void StampStrip::setDisplaySettings(const DisplaySettings& settings) {
  m_settings = settings;
  rerender();
}

void StampStrip::setFixedLimits(std::optional<std::pair<double, double>> limits) {
  m_fixed = limits;
  rerender();
}

void StampStrip::setPlaceholder(const QString& text) {
  m_placeholder = text;
  update();
}

QSize StampStrip::sizeHint() const {
  const int n = std::max(1, tileCount());
  return {n * 110, 150};
}

void StampStrip::rerender() {
  m_rendered.clear();
  std::vector<const Image*> images;
  for (const Tile& t : m_tiles)
    images.push_back(t.image.get());
  if (m_fixed)
    std::tie(m_lo, m_hi) = *m_fixed;
  else
    std::tie(m_lo, m_hi) = commonLimits(images, m_settings);
  for (const Tile& t : m_tiles)
    m_rendered.push_back(t.image && !t.image->empty() ? renderImage(*t.image, m_lo, m_hi, m_settings)
                                                      : QImage());
  update();
}

void StampStrip::paintEvent(QPaintEvent*) {
  QPainter p(this);
  p.fillRect(rect(), palette().window());
  if (m_tiles.empty()) {
    p.setPen(palette().color(QPalette::PlaceholderText));
    p.drawText(rect(), Qt::AlignCenter | Qt::TextWordWrap, m_placeholder);
    return;
  }
  const int n = tileCount();
  const int gap = 6;
  QFont small = font();
  small.setPointSizeF(std::max(6.0, small.pointSizeF() * 0.85));
  p.setFont(small);
  int lines = 1;
  for (const Tile& t : m_tiles)
    lines = std::max(lines, static_cast<int>(t.caption.count('\n')) + 1);
  const int captionH = lines * QFontMetrics(small).height() + 2;
  const int side = std::max(16, std::min((width() - gap * (n + 1)) / n, height() - captionH - 4));
  const int x0 = (width() - (n * side + (n - 1) * gap)) / 2;
  for (int i = 0; i < n; ++i) {
    const QRect box(x0 + i * (side + gap), 2, side, side);
    const QImage& img = m_rendered[static_cast<std::size_t>(i)];
    if (!img.isNull()) p.drawImage(box, img);
    // Centre marker: the candidate's cell.
    p.setPen(QPen(QColor(0, 220, 120, 170), 1));
    const QPoint c = box.center();
    p.drawLine(c.x() - side / 8, c.y(), c.x() - side / 20, c.y());
    p.drawLine(c.x() + side / 20, c.y(), c.x() + side / 8, c.y());
    if (m_tiles[static_cast<std::size_t>(i)].flagged) {
      p.setPen(QPen(QColor(230, 40, 40), 3));
      p.drawRect(box.adjusted(1, 1, -1, -1));
    }
    p.setPen(palette().color(QPalette::WindowText));
    const int slot = std::max(side + gap, width() / n);
    p.drawText(QRect(box.center().x() - slot / 2, box.bottom() + 2, slot, captionH),
               Qt::AlignHCenter | Qt::AlignTop, m_tiles[static_cast<std::size_t>(i)].caption);
  }
}

}  // namespace st::ui

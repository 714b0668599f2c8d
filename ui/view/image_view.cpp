#include "image_view.hpp"

#include <QKeyEvent>
#include <QMouseEvent>
#include <QPainter>
#include <QWheelEvent>
#include <algorithm>
#include <cmath>

namespace st::ui {

ImageView::ImageView(QWidget* parent) : QWidget(parent) {
  setFocusPolicy(Qt::StrongFocus);
  setMouseTracking(true);
  setMinimumSize(200, 200);
  setAttribute(Qt::WA_OpaquePaintEvent);
  m_placeholder = defaultPlaceholder();
}

QString ImageView::defaultPlaceholder() {
  return tr("Open a FITS cube (File → Open), a folder, drop files here, or open the demo observation "
            "(File → Open demo observation, Ctrl+D)");
}

void ImageView::setImage(std::shared_ptr<const Image> image, bool keepLimits) {
  const bool sameSize =
      m_image && image && m_image->width == image->width && m_image->height == image->height;
  m_image = std::move(image);
  if (!m_image || m_image->empty()) {
    clear();
    return;
  }
  if (!keepLimits || !sameSize) {
    std::tie(m_lo, m_hi) = computeLimits(m_image->data(), m_image->size(), m_settings);
  }
  m_rendered = renderImage(*m_image, m_lo, m_hi, m_settings);
  if (!sameSize) m_fitPending = true;
  if (m_fitPending && width() > 0) zoomToFit();
  update();
}

void ImageView::clear() {
  m_image.reset();
  m_rendered = QImage();
  m_markers.clear();
  update();
}

void ImageView::setDisplaySettings(const DisplaySettings& settings) {
  m_settings = settings;
  if (m_image) std::tie(m_lo, m_hi) = computeLimits(m_image->data(), m_image->size(), m_settings);
  rerender();
}

void ImageView::rerender() {
  if (m_image) m_rendered = renderImage(*m_image, m_lo, m_hi, m_settings);
  update();
}

void ImageView::setMarkers(std::vector<ImageMarker> markers) {
  m_markers = std::move(markers);
  update();
}

void ImageView::setOverlayText(const QString& text) {
  m_overlay = text;
  update();
}

void ImageView::setPlaceholder(const QString& text) {
  m_placeholder = text;
  update();
}

void ImageView::setZoom(double zoom) {
  zoomAbout(zoom / m_zoom, QPointF(width() / 2.0, height() / 2.0));
}

void ImageView::zoomToFit() {
  m_fitPending = false;
  if (m_rendered.isNull()) return;
  const double z = std::min(width() / static_cast<double>(m_rendered.width()),
                            height() / static_cast<double>(m_rendered.height()));
  m_zoom = std::clamp(z, 1.0 / 64, 64.0);
  m_offset =
      QPointF((width() - m_rendered.width() * m_zoom) / 2.0, (height() - m_rendered.height() * m_zoom) / 2.0);
  update();
}

void ImageView::zoomOneToOne() {
  if (m_rendered.isNull()) return;
  const QPointF centre = widgetToImage(QPointF(width() / 2.0, height() / 2.0));
  m_zoom = 1.0;
  centreOn(centre.x(), centre.y());
}

void ImageView::centreOn(double x, double y) {
  if (m_rendered.isNull()) return;
  const QPointF w = imageToWidget(QPointF(x, y));
  m_offset += QPointF(width() / 2.0, height() / 2.0) - w;
  update();
}

QPointF ImageView::widgetToImage(const QPointF& p) const {
  const double h = m_rendered.isNull() ? 0.0 : m_rendered.height();
  const double qx = (p.x() - m_offset.x()) / m_zoom;  // image coordinates with y down, pixel edges at ints
  const double qy = (p.y() - m_offset.y()) / m_zoom;
  return {qx - 0.5, h - qy - 0.5};
}

QPointF ImageView::imageToWidget(const QPointF& pixel) const {
  const double h = m_rendered.isNull() ? 0.0 : m_rendered.height();
  return {m_offset.x() + (pixel.x() + 0.5) * m_zoom, m_offset.y() + (h - pixel.y() - 0.5) * m_zoom};
}

void ImageView::zoomAbout(double factor, const QPointF& widgetPos) {
  const double newZoom = std::clamp(m_zoom * factor, 1.0 / 64, 64.0);
  const double f = newZoom / m_zoom;
  m_offset = widgetPos - (widgetPos - m_offset) * f;
  m_zoom = newZoom;
  update();
}

void ImageView::paintEvent(QPaintEvent*) {
  QPainter p(this);
  p.fillRect(rect(), QColor(24, 24, 28));
  if (m_rendered.isNull()) {
    p.setPen(QColor(150, 150, 160));
    p.drawText(rect(), Qt::AlignCenter | Qt::TextWordWrap, m_placeholder);
    return;
  }
  p.setRenderHint(QPainter::SmoothPixmapTransform, m_zoom < 1.0);
  const QRectF target(m_offset, QSizeF(m_rendered.width() * m_zoom, m_rendered.height() * m_zoom));
  p.drawImage(target, m_rendered);
  p.setRenderHint(QPainter::Antialiasing, true);
  for (const ImageMarker& m : m_markers) {
    const QPointF c = imageToWidget(m.pixel);
    const double r = std::max(5.0, m.radiusPx * m_zoom);
    p.setPen(QPen(m.colour, m.width));
    p.setBrush(Qt::NoBrush);
    p.drawEllipse(c, r, r);
    if (!m.label.isEmpty()) p.drawText(c + QPointF(r + 3, -r), m.label);
  }
  if (!m_overlay.isEmpty()) {
    // A dark band under the caption keeps it readable over bright images.
    const QRectF band = p.fontMetrics()
                            .boundingRect(m_overlay)
                            .adjusted(-6, -3, 6, 3)
                            .translated(14, 10 + p.fontMetrics().ascent());
    p.fillRect(band, QColor(0, 0, 0, 170));
    p.setPen(QColor(230, 230, 120));
    p.drawText(QRectF(8, 6, width() - 16, 20), Qt::AlignLeft | Qt::AlignTop, m_overlay);
  }
}

void ImageView::wheelEvent(QWheelEvent* event) {
  const double steps = event->angleDelta().y() / 120.0;
  zoomAbout(std::pow(1.25, steps), event->position());
  event->accept();
}

void ImageView::mousePressEvent(QMouseEvent* event) {
  m_pressPos = m_lastPos = event->position();
  m_dragging = false;
  setFocus();
}

void ImageView::mouseMoveEvent(QMouseEvent* event) {
  if (event->buttons() & (Qt::LeftButton | Qt::MiddleButton)) {
    if ((event->position() - m_pressPos).manhattanLength() > 3) m_dragging = true;
    if (m_dragging) {
      m_offset += event->position() - m_lastPos;
      update();
    }
    m_lastPos = event->position();
  }
  if (!m_image) return;
  const QPointF q = widgetToImage(event->position());
  const int x = static_cast<int>(std::lround(q.x()));
  const int y = static_cast<int>(std::lround(q.y()));
  if (m_image->contains(x, y)) {
    emit hovered(x, y, m_image->at(x, y), true);
  } else {
    emit hovered(x, y, 0.0, false);
  }
}

void ImageView::mouseReleaseEvent(QMouseEvent* event) {
  if (!m_dragging && event->button() == Qt::LeftButton && m_image) {
    const QPointF q = widgetToImage(event->position());
    emit clicked(q.x(), q.y());
  }
  m_dragging = false;
}

void ImageView::keyPressEvent(QKeyEvent* event) {
  const double pan = 40.0;
  switch (event->key()) {
    case Qt::Key_Plus:
    case Qt::Key_Equal:
      zoomAbout(1.25, QPointF(width() / 2.0, height() / 2.0));
      break;
    case Qt::Key_Minus:
      zoomAbout(0.8, QPointF(width() / 2.0, height() / 2.0));
      break;
    case Qt::Key_0:
      zoomToFit();
      break;
    case Qt::Key_1:
      zoomOneToOne();
      break;
    case Qt::Key_Left:
      m_offset.rx() += pan;
      update();
      break;
    case Qt::Key_Right:
      m_offset.rx() -= pan;
      update();
      break;
    case Qt::Key_Up:
      m_offset.ry() += pan;
      update();
      break;
    case Qt::Key_Down:
      m_offset.ry() -= pan;
      update();
      break;
    default:
      QWidget::keyPressEvent(event);
  }
}

void ImageView::resizeEvent(QResizeEvent*) {
  if (m_fitPending) zoomToFit();
}

void ImageView::leaveEvent(QEvent*) {
  emit hovered(0, 0, 0.0, false);
}

}  // namespace st::ui

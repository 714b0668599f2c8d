#pragma once
// The central image view: shows a float image through DisplaySettings, zoom and pan by wheel, drag and
// keys (+/- zoom, 0 fit, 1 one-to-one, arrows pan), with markers drawn on top. Image pixel (x, y) is 0-based
// with y up (row 0 at the bottom), as in DS9. The view only paints; rendering 512^2 takes a few ms.
#include <QImage>
#include <QPointF>
#include <QString>
#include <QWidget>
#include <memory>
#include <vector>

#include "image_render.hpp"
#include "st/common/image.hpp"

namespace st::ui {

/// A circle drawn over the image at a pixel position, with an optional label.
struct ImageMarker {
  QPointF pixel;
  double radiusPx = 6.0;
  QColor colour = QColor(0, 220, 120);
  QString label;
  double width = 1.5;  ///< pen width, screen pixels
};

class ImageView : public QWidget {
  Q_OBJECT
 public:
  explicit ImageView(QWidget* parent = nullptr);

  /// Shows `image`; keeps zoom and pan when the size is unchanged (scrubbing), else fits it. The limits are
  /// recomputed unless `keepLimits` (used while scrubbing so the brightness does not jump).
  void setImage(std::shared_ptr<const Image> image, bool keepLimits = false);
  [[nodiscard]] const std::shared_ptr<const Image>& image() const noexcept { return m_image; }
  void clear();

  void setDisplaySettings(const DisplaySettings& settings);
  [[nodiscard]] const DisplaySettings& displaySettings() const noexcept { return m_settings; }
  [[nodiscard]] std::pair<double, double> limits() const noexcept { return {m_lo, m_hi}; }
  /// The rendered colour image (what is on screen before zoom), for tests and export.
  [[nodiscard]] const QImage& rendered() const noexcept { return m_rendered; }

  void setMarkers(std::vector<ImageMarker> markers);
  [[nodiscard]] const std::vector<ImageMarker>& markers() const noexcept { return m_markers; }
  void setOverlayText(const QString& text);
  [[nodiscard]] const QString& overlayText() const noexcept { return m_overlay; }
  /// Text shown while there is no image.
  void setPlaceholder(const QString& text);
  /// What an empty view says: how to open a cube or the demo.
  [[nodiscard]] static QString defaultPlaceholder();
  [[nodiscard]] const QString& placeholder() const noexcept { return m_placeholder; }

  [[nodiscard]] double zoom() const noexcept { return m_zoom; }
  void setZoom(double zoom);
  void zoomToFit();
  void zoomOneToOne();
  /// Centres the view on image pixel (x, y).
  void centreOn(double x, double y);
  /// The image pixel under a widget position (continuous, 0-based, y up).
  [[nodiscard]] QPointF widgetToImage(const QPointF& p) const;
  [[nodiscard]] QPointF imageToWidget(const QPointF& pixel) const;

 signals:
  /// The pointer is over image pixel (x, y) (nearest integer) holding `value`; inside=false when it left.
  void hovered(int x, int y, double value, bool inside);
  /// A click without drag at image pixel (x, y).
  void clicked(double x, double y);

 protected:
  void paintEvent(QPaintEvent* event) override;
  void wheelEvent(QWheelEvent* event) override;
  void mousePressEvent(QMouseEvent* event) override;
  void mouseMoveEvent(QMouseEvent* event) override;
  void mouseReleaseEvent(QMouseEvent* event) override;
  void keyPressEvent(QKeyEvent* event) override;
  void resizeEvent(QResizeEvent* event) override;
  void leaveEvent(QEvent* event) override;

 private:
  void rerender();
  void zoomAbout(double factor, const QPointF& widgetPos);

  std::shared_ptr<const Image> m_image;
  QImage m_rendered;
  DisplaySettings m_settings;
  double m_lo = 0.0;
  double m_hi = 1.0;
  double m_zoom = 1.0;
  QPointF m_offset;  // widget position of the image's top-left corner
  bool m_fitPending = true;
  QPointF m_pressPos;
  QPointF m_lastPos;
  bool m_dragging = false;
  std::vector<ImageMarker> m_markers;
  QString m_overlay;
  QString m_placeholder;
};

}  // namespace st::ui

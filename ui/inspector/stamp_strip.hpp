#pragma once
// A row of small images (stamps) drawn on one display scale, each with a caption; flagged tiles get a red
// frame. Used for "tracking the sky | tracking the candidate", the segment strip and the frame movie. The
// limits are computed over all tiles together (so brightness compares across tiles) unless fixed with
// setFixedLimits. Rendering is a few small images: cheap enough for the GUI thread.
#include <QImage>
#include <QString>
#include <QWidget>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "image_render.hpp"
#include "st/common/image.hpp"

namespace st::ui {

class StampStrip : public QWidget {
  Q_OBJECT
 public:
  struct Tile {
    std::shared_ptr<const Image> image;
    QString caption;
    bool flagged = false;
  };

  explicit StampStrip(QWidget* parent = nullptr);

  void setTiles(std::vector<Tile> tiles);
  void clear();
  /// Display settings (default: linear, 99.5 % limits, inferno).
  void setDisplaySettings(const DisplaySettings& settings);
  /// Fixed display limits (e.g. a movie's, computed over every frame); nullopt: computed over the tiles.
  void setFixedLimits(std::optional<std::pair<double, double>> limits);
  void setPlaceholder(const QString& text);

  [[nodiscard]] int tileCount() const noexcept { return static_cast<int>(m_tiles.size()); }
  [[nodiscard]] const Tile& tile(int i) const { return m_tiles.at(static_cast<std::size_t>(i)); }
  [[nodiscard]] const DisplaySettings& displaySettings() const noexcept { return m_settings; }
  /// The limits the tiles are drawn with.
  [[nodiscard]] std::pair<double, double> limits() const noexcept { return {m_lo, m_hi}; }

  [[nodiscard]] QSize sizeHint() const override;

 protected:
  void paintEvent(QPaintEvent* event) override;

 private:
  void rerender();

  std::vector<Tile> m_tiles;
  std::vector<QImage> m_rendered;
  DisplaySettings m_settings;
  std::optional<std::pair<double, double>> m_fixed;
  double m_lo = 0.0;
  double m_hi = 1.0;
  QString m_placeholder;
};

/// Display limits over several images together (computeLimits on their pooled pixels).
[[nodiscard]] std::pair<double, double> commonLimits(const std::vector<const Image*>& images,
                                                     const DisplaySettings& settings);

}  // namespace st::ui

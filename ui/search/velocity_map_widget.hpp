#pragma once
// Velocity space: the search's velocity map (max SNR over pixels per grid velocity) as a heatmap with a
// colour scale, axes relative to the sky rate in the chosen unit (the sky rate is the origin), candidates (circles), the sky rate (cross) and the current
// velocity (crosshair). Click or drag to scrub; arrow keys step one grid cell; a readout shows velocity and
// SNR under the cursor. Before a search it shows the empty grid plane, so scrubbing works already.
#include <QWidget>
#include <array>

#include "observation.hpp"

class QCustomPlot;
class QCPColorMap;
class QCPColorScale;
class QCPGraph;
class QCPItemText;
class QLabel;

namespace st::ui {

class VelocityMapWidget : public QWidget {
  Q_OBJECT
 public:
  VelocityMapWidget(Observation* observation, QWidget* parent = nullptr);

  /// The velocity (px/s) at a widget position of the plot; snapped to the nearest grid velocity.
  [[nodiscard]] Velocity velocityAtPlotPixel(const QPointF& pos) const;
  /// Plot-pixel position of a velocity (px/s), for tests.
  [[nodiscard]] QPointF plotPixelOf(Velocity v) const;
  [[nodiscard]] QCustomPlot* plot() const noexcept { return m_plot; }
  /// Candidates drawn with `label`'s colour (the ones the table's filters show), for tests.
  [[nodiscard]] int candidatePoints(session::Label label) const;

 protected:
  void keyPressEvent(QKeyEvent* event) override;

 private:
  void rebuild();
  void updateMarkers();
  /// The candidates' circles: the ones the table shows, coloured by label.
  void updateCandidates();
  void onMouse(QMouseEvent* event, bool press);
  /// A velocity (px/s) to the axes (relative to the sky rate, in the shown unit; motion_vs_sky.hpp) and back.
  [[nodiscard]] QPointF toAxes(Velocity v) const;
  [[nodiscard]] Velocity fromAxes(QPointF p) const;

  Observation* m_obs;
  QCustomPlot* m_plot = nullptr;
  QCPColorMap* m_map = nullptr;
  QCPColorScale* m_scale = nullptr;
  /// The candidates by label (unvetted, real, artifact, unsure), coloured as the DS9 regions.
  std::array<QCPGraph*, 4> m_candidates{};
  QCPGraph* m_sky = nullptr;
  QCPGraph* m_current = nullptr;
  QLabel* m_readout = nullptr;  ///< objectName "velocityMap.readout"
  QLabel* m_legend = nullptr;
  QCPItemText* m_hint = nullptr;
};

}  // namespace st::ui

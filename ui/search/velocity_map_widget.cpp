#include "velocity_map_widget.hpp"

#include <qcustomplot.h>
#include <QKeyEvent>
#include <QLabel>
#include <QVBoxLayout>
#include <algorithm>
#include <cmath>

#include "image_render.hpp"
#include "motion_vs_sky.hpp"

namespace st::ui {

VelocityMapWidget::VelocityMapWidget(Observation* observation, QWidget* parent)
    : QWidget(parent), m_obs(observation) {
  setFocusPolicy(Qt::StrongFocus);
  m_plot = new QCustomPlot(this);
  m_plot->setMinimumSize(260, 220);
  m_plot->setFocusPolicy(Qt::NoFocus);
  m_plot->xAxis->ticker()->setTickCount(4);  // rates like 117.5 deg/day need room
  m_plot->yAxis->ticker()->setTickCount(5);
  m_map = new QCPColorMap(m_plot->xAxis, m_plot->yAxis);
  m_scale = new QCPColorScale(m_plot);
  m_plot->plotLayout()->addElement(0, 1, m_scale);
  m_scale->setType(QCPAxis::atRight);
  m_scale->axis()->setLabel("max SNR");
  m_map->setColorScale(m_scale);
  QCPColorGradient viridis;  // the same viridis as the image view (QCustomPlot 2.0 has no preset)
  viridis.clearColorStops();
  const auto& table = colormapTable(Colormap::Viridis);
  for (int i = 0; i <= 16; ++i)
    viridis.setColorStopAt(i / 16.0, QColor(table[static_cast<std::size_t>(std::min(255, i * 16))]));
  m_map->setGradient(viridis);
  m_map->setInterpolate(false);
  auto* margins = new QCPMarginGroup(m_plot);
  m_plot->axisRect()->setMarginGroup(QCP::msBottom | QCP::msTop, margins);
  m_scale->setMarginGroup(QCP::msBottom | QCP::msTop, margins);

  auto makeGraph = [&](QCPScatterStyle style, const QString& name) {
    QCPGraph* g = m_plot->addGraph();
    g->setLineStyle(QCPGraph::lsNone);
    g->setScatterStyle(style);
    g->setName(name);
    return g;
  };
  for (const auto label : {session::Label::Unvetted, session::Label::Real, session::Label::Artifact,
                           session::Label::Unsure})
    m_candidates[static_cast<std::size_t>(label)] = makeGraph(
        QCPScatterStyle(QCPScatterStyle::ssCircle, QPen(QColor(candidate::labelColour(label)), 1.5), Qt::NoBrush,
                        11),
        QString("candidates (%1)").arg(session::toString(label)));
  m_sky =
      makeGraph(QCPScatterStyle(QCPScatterStyle::ssCross, QPen(Qt::white, 2), Qt::NoBrush, 12), "sky rate");
  m_current =
      makeGraph(QCPScatterStyle(QCPScatterStyle::ssPlusCircle, QPen(QColor(255, 200, 0), 2), Qt::NoBrush, 14),
                "current");
  m_hint = new QCPItemText(m_plot);
  m_hint->position->setType(QCPItemPosition::ptAxisRectRatio);
  m_hint->position->setCoords(0.5, 0.12);
  m_hint->setColor(Qt::white);
  m_hint->setText("no search yet");
  m_legend = new QLabel(
      "○ candidates: <span style='color:cyan'>unvetted</span> <span style='color:green'>real</span> "
      "<span style='color:red'>artifact</span> <span style='color:#d4a000'>unsure</span> &nbsp; ✕ sky rate &nbsp; "
      "<span style='color:#d4a000'>⊕</span> current velocity",
      this);
  m_readout = new QLabel(this);
  m_readout->setObjectName("velocityMap.readout");
  m_readout->setTextInteractionFlags(Qt::TextSelectableByMouse);
  auto* layout = new QVBoxLayout(this);
  layout->setContentsMargins(2, 2, 2, 2);
  layout->addWidget(m_plot, 1);
  layout->addWidget(m_legend);
  layout->addWidget(m_readout);

  connect(m_plot, &QCustomPlot::mousePress, this, [this](QMouseEvent* e) { onMouse(e, true); });
  connect(m_plot, &QCustomPlot::mouseMove, this, [this](QMouseEvent* e) { onMouse(e, false); });
  connect(m_obs, &Observation::resultChanged, this, &VelocityMapWidget::rebuild);
  connect(m_obs, &Observation::gridChanged, this, &VelocityMapWidget::rebuild);
  connect(m_obs, &Observation::unitChanged, this, &VelocityMapWidget::rebuild);
  // The axes are relative to the sky rate, which pre-processing measures.
  connect(m_obs, &Observation::preparedChanged, this, &VelocityMapWidget::rebuild);
  connect(m_obs, &Observation::candidatesShownChanged, this, &VelocityMapWidget::updateCandidates);
  connect(m_obs, &Observation::candidateStateChanged, this, &VelocityMapWidget::updateCandidates);
  connect(m_obs, &Observation::velocityChanged, this, &VelocityMapWidget::updateMarkers);
  rebuild();
}

QPointF VelocityMapWidget::toAxes(Velocity v) const {
  const Velocity shown = toShownVsSky(*m_obs, v);
  return {shown.vx, shown.vy};
}
Velocity VelocityMapWidget::fromAxes(QPointF p) const {
  return fromShownVsSky(*m_obs, {p.x(), p.y()});
}

void VelocityMapWidget::rebuild() {
  // The readout described the map under the pointer: another observation, search or unit makes it stale.
  m_readout->clear();
  // Motion relative to the stars, as the candidates table (motion_vs_sky.hpp): the sky rate is the origin.
  const QString unit = unitLabel(shownUnit(*m_obs));
  m_plot->xAxis->setLabel("vx vs sky [" + unit + "]");
  m_plot->yAxis->setLabel("vy vs sky [" + unit + "]");
  const auto& result = m_obs->result();
  // The last search's map stays (on its own grid) until a new search completes, also while the panel's grid
  // is being changed or a new search runs; before any search the panel's grid plane is shown for scrubbing.
  const bool haveResultMap = result && result->grid.nvx > 0 && result->grid.nvy > 0 &&
                             result->map.nvx == result->grid.nvx && result->map.nvy == result->grid.nvy;
  const search::VelocityGrid& grid = haveResultMap ? result->grid : m_obs->grid();
  if (grid.nvx > 0 && grid.nvy > 0) {
    const Velocity lo = grid.at(0, 0);
    const Velocity hi = grid.at(grid.nvx - 1, grid.nvy - 1);
    m_map->data()->setSize(grid.nvx, grid.nvy);
    const QPointF loAxes = toAxes(lo);
    const QPointF hiAxes = toAxes(hi);
    m_map->data()->setRange(QCPRange(loAxes.x(), hiAxes.x()), QCPRange(loAxes.y(), hiAxes.y()));
    const bool haveMap = haveResultMap;
    for (int iy = 0; iy < grid.nvy; ++iy)
      for (int ix = 0; ix < grid.nvx; ++ix)
        m_map->data()->setCell(
            ix, iy, haveMap ? result->map.maxSnr[static_cast<std::size_t>(iy) * grid.nvx + ix] : 0.0);
    m_map->rescaleDataRange(true);
    m_hint->setVisible(!haveMap);
    const double half = 0.5 * grid.stepPxS;
    const QPointF from = toAxes({lo.vx - half, lo.vy - half});
    const QPointF to = toAxes({hi.vx + half, hi.vy + half});
    m_plot->xAxis->setRange(from.x(), to.x());
    m_plot->yAxis->setRange(from.y(), to.y());
    m_map->setVisible(true);
  } else {
    m_map->setVisible(false);
  }
  updateCandidates();
  updateMarkers();
}

int VelocityMapWidget::candidatePoints(session::Label label) const {
  return m_candidates[static_cast<std::size_t>(label)]->dataCount();
}

void VelocityMapWidget::updateCandidates() {
  std::array<QVector<double>, 4> cx, cy;
  if (const auto& result = m_obs->result()) {
    for (std::size_t i = 0; i < result->candidates.size(); ++i) {
      const int index = static_cast<int>(i);
      if (!m_obs->candidateShown(index)) continue;
      const auto* state = m_obs->candidateState(index);
      const auto k = static_cast<std::size_t>(state ? state->label : session::Label::Unvetted);
      const QPointF at = toAxes(result->candidates[i].v);
      cx[k].push_back(at.x());
      cy[k].push_back(at.y());
    }
  }
  for (std::size_t k = 0; k < m_candidates.size(); ++k)
    m_candidates[k]->setData(cx[k], cy[k]);
  m_plot->replot(QCustomPlot::rpQueuedReplot);
}

void VelocityMapWidget::updateMarkers() {
  const QPointF sky = toAxes(m_obs->skyRate());  // the origin
  m_sky->setData({sky.x()}, {sky.y()});
  const QPointF v = toAxes(m_obs->velocity());
  m_current->setData({v.x()}, {v.y()});
  m_plot->replot(QCustomPlot::rpQueuedReplot);
}

Velocity VelocityMapWidget::velocityAtPlotPixel(const QPointF& pos) const {
  const Velocity at = fromAxes({m_plot->xAxis->pixelToCoord(pos.x()), m_plot->yAxis->pixelToCoord(pos.y())});
  const double vx = at.vx;
  const double vy = at.vy;
  const search::VelocityGrid& g = m_obs->grid();
  if (g.nvx <= 0 || g.nvy <= 0 || g.stepPxS <= 0) return {vx, vy};
  const auto snap = [&](double v, double c, int n) {
    const double i = std::round((v - c) / g.stepPxS + 0.5 * (n - 1));
    return static_cast<int>(std::clamp(i, 0.0, n - 1.0));
  };
  return g.at(snap(vx, g.centre.vx, g.nvx), snap(vy, g.centre.vy, g.nvy));
}

QPointF VelocityMapWidget::plotPixelOf(Velocity v) const {
  const QPointF at = toAxes(v);
  return {m_plot->xAxis->coordToPixel(at.x()), m_plot->yAxis->coordToPixel(at.y())};
}

void VelocityMapWidget::onMouse(QMouseEvent* event, bool press) {
  const Velocity v = velocityAtPlotPixel(event->position());
  const search::VelocityGrid& g = m_obs->grid();
  QString snr;
  const auto& result = m_obs->result();
  if (result && g.stepPxS > 0 && result->map.nvx == g.nvx) {
    const int ix = static_cast<int>(std::lround((v.vx - g.centre.vx) / g.stepPxS + 0.5 * (g.nvx - 1)));
    const int iy = static_cast<int>(std::lround((v.vy - g.centre.vy) / g.stepPxS + 0.5 * (g.nvy - 1)));
    if (ix >= 0 && iy >= 0 && ix < g.nvx && iy < g.nvy) {
      const std::size_t k = static_cast<std::size_t>(iy) * g.nvx + ix;
      snr = QString("   max SNR %1 at (%2, %3)")
                .arg(result->map.maxSnr[k], 0, 'f', 2)
                .arg(result->map.argX[k])
                .arg(result->map.argY[k]);
    }
  }
  // The motion under the pointer as the table shows it; the PA where the map's best pixel is (or the middle).
  double px = m_obs->raw() ? 0.5 * (m_obs->raw()->width() - 1) : 0.0;
  double py = m_obs->raw() ? 0.5 * (m_obs->raw()->height() - 1) : 0.0;
  if (!snr.isEmpty()) {
    const int ix = static_cast<int>(std::lround((v.vx - g.centre.vx) / g.stepPxS + 0.5 * (g.nvx - 1)));
    const int iy = static_cast<int>(std::lround((v.vy - g.centre.vy) / g.stepPxS + 0.5 * (g.nvy - 1)));
    const std::size_t k = static_cast<std::size_t>(iy) * g.nvx + ix;
    px = result->map.argX[k];
    py = result->map.argY[k];
  }
  m_readout->setText(describeMotionWithComponents(motionVsSky(*m_obs, px, py, v)) + snr);
  if (press || (event->buttons() & Qt::LeftButton)) {
    setFocus();
    m_obs->setVelocity(v);
  }
}

void VelocityMapWidget::keyPressEvent(QKeyEvent* event) {
  const search::VelocityGrid& g = m_obs->grid();
  const double step = g.stepPxS > 0 ? g.stepPxS : 0.01;
  Velocity v = m_obs->velocity();
  switch (event->key()) {
    case Qt::Key_Left:
      v.vx -= step;
      break;
    case Qt::Key_Right:
      v.vx += step;
      break;
    case Qt::Key_Up:
      v.vy += step;
      break;
    case Qt::Key_Down:
      v.vy -= step;
      break;
    default:
      QWidget::keyPressEvent(event);
      return;
  }
  m_obs->setVelocity(v);
}

}  // namespace st::ui

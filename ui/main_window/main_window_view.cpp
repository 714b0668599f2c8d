// MainWindow: what the central view shows (frames, intermediates, the live stack), markers and readouts.
#include <QComboBox>
#include <QLabel>
#include <QSpinBox>

#include "image_view.hpp"
#include "inspector_panel.hpp"
#include "main_window.hpp"
#include "motion_vs_sky.hpp"
#include "out_of_core_controller.hpp"
#include "stack_scrubber.hpp"

namespace st::ui {
namespace {
std::shared_ptr<const Image> frameOf(const FrameCube& cube, int n) {
  if (cube.empty()) return nullptr;
  const int k = std::clamp(n, 0, static_cast<int>(cube.frameCount()) - 1);
  return std::make_shared<const Image>(cube.frameImage(static_cast<std::size_t>(k)));
}
}  // namespace

void MainWindow::refreshSourceList() {
  const QSignalBlocker block(m_sourceCombo);
  const int previous = m_sourceCombo->currentData().isValid() ? m_sourceCombo->currentData().toInt() : 0;
  m_sourceCombo->clear();
  const auto& raw = m_obs->raw();
  const auto& prepared = m_obs->prepared();
  if (outOfCore()) {  // one image in memory, the mean; stacks summed in strips from the file
    m_sourceCombo->addItem("Mean of all frames (out of core)", static_cast<int>(Source::RawFrame));
    m_sourceCombo->addItem("Stack at velocity (out of core, in strips)", static_cast<int>(Source::Stack));
  } else if (raw) {
    m_sourceCombo->addItem("Raw frame", static_cast<int>(Source::RawFrame));
  }
  if (prepared && !outOfCore()) {
    for (std::size_t k = 0; k < prepared->layers.size(); ++k)
      m_sourceCombo->addItem(QString::fromStdString(prepared->layers[k].first),
                             static_cast<int>(Source::Layer) + static_cast<int>(k));
    if (prepared->unfiltered)
      m_sourceCombo->addItem("Unfiltered frame", static_cast<int>(Source::UnfilteredFrame));
    if (prepared->filtered) {
      m_sourceCombo->addItem("Filtered frame", static_cast<int>(Source::FilteredFrame));
      m_sourceCombo->addItem("Live stack at velocity", static_cast<int>(Source::Stack));
    }
  }
  const int index = m_sourceCombo->findData(previous);
  m_sourceCombo->setCurrentIndex(index >= 0 ? index : 0);
}

void MainWindow::showSource(Source source, int layer) {
  const int code = static_cast<int>(source) + (source == Source::Layer ? layer : 0);
  const int index = m_sourceCombo->findData(code);
  if (index < 0) return;
  if (index == m_sourceCombo->currentIndex())
    refreshCentral();
  else
    m_sourceCombo->setCurrentIndex(index);
}

void MainWindow::refreshCentral() {
  const QVariant current = m_sourceCombo->currentData();
  if (!current.isValid()) {
    m_view->clear();
    return;
  }
  const int code = current.toInt();
  const auto source =
      static_cast<Source>(code >= static_cast<int>(Source::Layer) ? static_cast<int>(Source::Layer) : code);
  const bool frames =
      source == Source::RawFrame || source == Source::FilteredFrame || source == Source::UnfilteredFrame;
  m_frameSpin->setEnabled(frames);
  const auto& prepared = m_obs->prepared();
  m_centralShowsStack = false;
  switch (source) {
    case Source::RawFrame:
      if (m_obs->raw()) m_view->setImage(frameOf(*m_obs->raw(), m_frameSpin->value()), true);
      if (outOfCore())
        m_view->setOverlayText("mean of all frames (out of core: read in strips)");
      else
        m_view->setOverlayText(QString("raw frame %1").arg(m_frameSpin->value()));
      break;
    case Source::FilteredFrame:
      if (prepared && prepared->filtered)
        m_view->setImage(frameOf(prepared->filtered->frames, m_frameSpin->value()));
      m_view->setOverlayText(QString("matched-filtered frame %1").arg(m_frameSpin->value()));
      break;
    case Source::UnfilteredFrame:
      if (prepared && prepared->unfiltered)
        m_view->setImage(frameOf(prepared->unfiltered->frames, m_frameSpin->value()));
      m_view->setOverlayText(QString("unfiltered frame %1").arg(m_frameSpin->value()));
      break;
    case Source::Layer: {
      const auto k = static_cast<std::size_t>(code - static_cast<int>(Source::Layer));
      if (prepared && k < prepared->layers.size()) {
        m_view->setImage(std::make_shared<const Image>(prepared->layers[k].second));
        m_view->setOverlayText(QString::fromStdString(prepared->layers[k].first));
      }
      break;
    }
    case Source::Stack:
      requestCentralStack();
      break;
  }
  updateMarkers();
}

void MainWindow::requestCentralStack() {
  if (static_cast<Source>(m_sourceCombo->currentData().toInt()) != Source::Stack) return;
  if (outOfCore()) {
    const Velocity v = m_obs->velocity();
    OutOfCoreController::of(this)->requestStack(v);
    const Velocity shown = toShownVsSky(*m_obs, v);
    m_view->setOverlayText(QString("summing the IPSA stack at v = (%1, %2) %3 vs sky in strips (out of core)…")
                               .arg(shown.vx, 0, 'g', 4)
                               .arg(shown.vy, 0, 'g', 4)
                               .arg(unitLabel(shownUnit(*m_obs))));
    return;
  }
  auto cube = m_inspector->stackCube();
  if (!cube) return;
  const Velocity v = m_obs->velocity();
  m_scrubber->request(cube, v, m_obs->stackMode(), kCentralTag);
  const Velocity shown = toShownVsSky(*m_obs, v);  // relative to the stars, as the table and the map
  m_view->setOverlayText(QString("%1 %2 stack at v = (%3, %4) %5 vs sky")
                             .arg(m_obs->stackMode() == search::StackMode::Ipsa ? "IPSA" : "CSA")
                             .arg(m_inspector->useUnfiltered() ? "unfiltered" : "filtered")
                             .arg(shown.vx, 0, 'g', 4)
                             .arg(shown.vy, 0, 'g', 4)
                             .arg(unitLabel(shownUnit(*m_obs))));
}

void MainWindow::updateMarkers() {
  std::vector<ImageMarker> markers;
  const auto& result = m_obs->result();
  if (result) {
    const auto selected = m_obs->selected();
    // Coloured by label as in the DS9 regions; hidden when the table's filters hide the candidate (the
    // selected one stays, drawn thicker).
    int drawn = 0;
    for (std::size_t i = 0; i < result->candidates.size() && drawn < 100; ++i) {
      const auto& c = result->candidates[i];
      const int index = static_cast<int>(i);
      const bool isSelected = selected && *selected == index;
      if (!isSelected && !m_obs->candidateShown(index)) continue;
      const auto* state = m_obs->candidateState(index);
      ImageMarker m;
      m.pixel = QPointF(c.x, c.y);
      m.radiusPx = isSelected ? 10.0 : 8.0;
      m.width = isSelected ? 3.0 : 1.5;
      if (i < 10 || isSelected) m.label = QString("#%1").arg(i + 1);
      m.colour = QColor(candidate::labelColour(state ? state->label : session::Label::Unvetted));
      markers.push_back(m);
      ++drawn;
    }
  }
  m_view->setMarkers(std::move(markers));
}

void MainWindow::onHover(int x, int y, double value, bool inside) {
  if (!inside) {
    m_pixelLabel->clear();
    return;
  }
  QString text = QString("x %1  y %2  value %3").arg(x).arg(y).arg(value, 0, 'g', 6);
  if (m_obs->raw() && m_services.pixelToSky) {
    try {
      if (const auto sky = m_services.pixelToSky(*m_obs->raw(), x, y)) {
        const double ra = sky->first / 15.0;
        const int h = static_cast<int>(ra);
        const int m = static_cast<int>((ra - h) * 60);
        const double s = ((ra - h) * 60 - m) * 60;
        const double dec = std::abs(sky->second);
        const int d = static_cast<int>(dec);
        const int dm = static_cast<int>((dec - d) * 60);
        const double ds = ((dec - d) * 60 - dm) * 60;
        text += QString("   RA %1h%2m%3s  Dec %4%5°%6'%7\"")
                    .arg(h, 2, 10, QChar('0'))
                    .arg(m, 2, 10, QChar('0'))
                    .arg(s, 5, 'f', 2, QChar('0'))
                    .arg(sky->second < 0 ? "-" : "+")
                    .arg(d, 2, 10, QChar('0'))
                    .arg(dm, 2, 10, QChar('0'))
                    .arg(ds, 4, 'f', 1, QChar('0'));
      }
    } catch (const std::exception&) {
      // outside the projection: no sky position to show
    }
  }
  m_pixelLabel->setText(text);
}

}  // namespace st::ui

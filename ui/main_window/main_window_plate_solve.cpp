// MainWindow: plate solving from the GUI (issue 15 item 5). When the loaded frames have no WCS a banner above
// the image says what is missing (RA/Dec, the compass, ADES) and offers "Plate solve"; Run > Plate solve does
// the same. The solve runs as a JobRunner job (cancellable; progress and Cancel in the status bar) through
// core's pipeline::plateSolveObservation (astrometry.net's solve-field, the same star lists and hints as
// `synthtrack-cli preprocess --plate-solve`); its error (solve-field missing, no index files, no solution in
// the time limit, solve-field's stderr) stays readable in the banner. On success the WCS is attached to the
// observation's cubes (Observation::attachWcs): RA/Dec, the compass, fits' sky positions and ADES use it.
#include <QAction>
#include <QFrame>
#include <QHBoxLayout>
#include <QLabel>
#include <QMenu>
#include <QPushButton>
#include <QStatusBar>
#include <QVBoxLayout>

#include "job_runner.hpp"
#include "main_window.hpp"
#include "plate_solve_settings.hpp"
#include "st/pipeline/preprocess.hpp"
#include "st/pipeline/solve_observation.hpp"

namespace st::ui {

void MainWindow::buildWcsBanner() {
  m_wcsBanner = new QFrame(centralWidget());
  m_wcsBanner->setObjectName("wcs.banner");
  m_wcsBanner->setStyleSheet(
      "#wcs\\.banner { background: #e4efff; border-bottom: 1px solid #6b8fc7; } QLabel { color: #1d3557; }");
  m_wcsText = new QLabel(m_wcsBanner);
  m_wcsText->setObjectName("wcs.text");
  m_wcsText->setWordWrap(true);
  m_wcsText->setTextInteractionFlags(Qt::TextSelectableByMouse);
  m_wcsSolve = new QPushButton("Plate solve", m_wcsBanner);
  m_wcsSolve->setObjectName("wcs.solve");
  m_wcsSolve->setToolTip("Find the WCS with astrometry.net's solve-field from the stars of the frames");
  auto* settings = new QPushButton("Settings…", m_wcsBanner);
  auto* row = new QHBoxLayout(m_wcsBanner);
  row->setContentsMargins(8, 4, 8, 4);
  row->addWidget(m_wcsText, 1);
  row->addWidget(m_wcsSolve);
  row->addWidget(settings);
  if (auto* layout = qobject_cast<QVBoxLayout*>(centralWidget()->layout())) layout->insertWidget(0, m_wcsBanner);
  m_wcsBanner->hide();
  connect(m_wcsSolve, &QPushButton::clicked, this, &MainWindow::runPlateSolve);
  connect(settings, &QPushButton::clicked, this, [this] {
    PlateSolveSettings s = PlateSolveSettings::load();
    editPlateSolveSettings(s, this);
  });
  connect(m_obs, &Observation::rawChanged, this, [this] {
    m_plateSolveError.clear();
    updateWcsBanner();
  });
  connect(m_obs, &Observation::wcsChanged, this, [this] {
    updateWcsBanner();
    updateMarkers();
    m_obs->setUnit(m_obs->unit());  // tables, axes and captions re-read the plate scale and the PA
  });
  connect(m_jobs, &JobRunner::started, this, [this](JobKind) { updateWcsBanner(); });
  connect(m_jobs, &JobRunner::finished, this,
          [this](JobKind kind, bool ok, bool cancelled, const QString& message, double) {
            if (kind == JobKind::PlateSolve)
              m_plateSolveError = cancelled ? QString("Plate solving was cancelled.") : ok ? QString() : message;
            updateWcsBanner();
          });
}

void MainWindow::buildPlateSolveActions(QMenu* run) {
  m_plateSolveAction = run->addAction("Plate s&olve (astrometry.net)", this, &MainWindow::runPlateSolve);
  m_plateSolveAction->setObjectName("action.plateSolve");
  m_plateSolveAction->setToolTip("Find a WCS for frames that have none (solve-field)");
  run->addAction("Plate solve settings…", this, [this] {
    PlateSolveSettings s = PlateSolveSettings::load();
    editPlateSolveSettings(s, this);
  });
}

void MainWindow::updateWcsBanner() {
  const auto& raw = m_obs->raw();
  const bool missing = raw && !raw->wcs;
  const bool solving = m_jobs->busy() && m_jobs->currentKind() == JobKind::PlateSolve;
  if (m_plateSolveAction) m_plateSolveAction->setEnabled(missing && !m_jobs->busy());
  m_wcsBanner->setVisible(missing);
  if (!missing) return;
  m_wcsSolve->setEnabled(!m_jobs->busy());
  m_wcsSolve->setText(m_plateSolveError.isEmpty() ? "Plate solve" : "Try again");
  QString text = "<b>No WCS:</b> the frames' header has no sky coordinates, so RA/Dec, the N/E compass and "
                 "ADES/MPC reports are not available.";
  if (solving)
    text = "<b>Plate solving</b> with astrometry.net's solve-field… (progress and Cancel in the status bar)";
  else if (!m_plateSolveError.isEmpty())
    text = "<b>Plate solving failed:</b> " + m_plateSolveError.toHtmlEscaped();
  m_wcsText->setText(text);
}

bool MainWindow::runPlateSolve() {
  const std::shared_ptr<const FrameCube> raw = m_obs->raw();
  if (!raw) {
    statusBar()->showMessage("Plate solve: open frames first", 10000);
    return false;
  }
  if (m_jobs->busy()) {
    statusBar()->showMessage("Plate solve: wait for " + m_jobs->currentName().toLower() + " to finish", 10000);
    return false;
  }
  const std::shared_ptr<const PreparedView> prepared = m_obs->prepared();
  const astro::PlateSolveParams params = PlateSolveSettings::load().params();
  m_plateSolveError.clear();
  const bool started = m_jobs->start(
      JobKind::PlateSolve,
      [this, raw, prepared, params](ProgressSink& progress, CancelToken& cancel) -> std::function<void()> {
        pipeline::ObservationSolveInput in;
        in.raw = raw.get();
        if (prepared && prepared->products && prepared->filtered) {
          in.catalogue = &prepared->products->stars;
          in.catalogueFrames = &prepared->filtered->frames;
          in.skyRate = prepared->filtered->skyRate;
        }
        auto solved = std::make_shared<const pipeline::ObservationSolve>(
            pipeline::plateSolveObservation(in, params, progress, cancel));
        return [this, raw, solved] {
          if (m_obs->raw() != raw) return;  // another observation was opened meanwhile
          m_plateSolveSummary = QString::fromStdString(solved->summary);
          m_obs->attachWcs(solved->solution.wcs, solved->solution.scaleArcsecPerPx);
          statusBar()->showMessage("WCS " + m_plateSolveSummary, 60000);
        };
      });
  updateWcsBanner();
  return started;
}

}  // namespace st::ui

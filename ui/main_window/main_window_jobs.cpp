// MainWindow: loading, pre-processing and searching (the command-line script: ui/script/script_runner.hpp).
// Every job's work runs on the JobRunner thread; only the returned closures touch the window
// (job_runner.hpp).
#include <QApplication>
#include <QComboBox>
#include <QDir>
#include <QFileInfo>
#include <QLabel>
#include <QProgressBar>
#include <QPushButton>
#include <QSpinBox>
#include <QStatusBar>
#include <QTimer>
#include <cstdio>

#include "calibration_files.hpp"
#include "candidate_table.hpp"
#include "image_view.hpp"
#include "inspector_panel.hpp"
#include "job_runner.hpp"
#include "out_of_core_controller.hpp"
#include "main_window.hpp"
#include "processing_panel.hpp"
#include "st/common/error.hpp"
#include "st/search/demo_grid.hpp"
#include "search_panel.hpp"
#include "session_controller.hpp"
#include "st/pipeline/demo_search.hpp"
#include "st/pipeline/prepared_cube.hpp"
#include "st/search/method_choice.hpp"
#include "st/search/velocity_grid.hpp"
#include "stack_scrubber.hpp"

namespace st::ui {

void MainWindow::sayBusy() {
  statusBar()->showMessage("Busy: " + m_jobs->currentName() + " is running", 4000);
}

void MainWindow::openInputs(const QStringList& paths) {
  if (paths.isEmpty()) return;
  if (m_jobs->busy()) return sayBusy();  // as openDemo: nothing changes while another job runs
  std::vector<std::string> inputs;
  for (const QString& p : paths)
    inputs.push_back(QFileInfo(p).absoluteFilePath().toStdString());
  auto load = m_services.loadFrames;
  const QString label =
      paths.size() == 1 ? QFileInfo(paths.front()).fileName() : QString("%1 inputs").arg(paths.size());
  m_demoGrid = false;
  m_processing->clearFiles();
  const CalibrationOffer offer = offerCalibrationFolders(paths);
  if (!offer.folders.empty()) m_processing->offerFiles(offer.folders, offer.note);
  m_session->prepareNew(inputs, false);
  // A cube larger than the memory budget opens out of core, raw frames whose pre-processing needs more are
  // pre-processed out of core (with the calibration folders offered beside them) and their filtered cube
  // opened so (out_of_core_controller.hpp); the decision reads headers, in the worker, through the planOpen
  // service.
  OutOfCoreController* ooc = OutOfCoreController::of(this);
  const std::size_t budget = ooc->budget().bytes;
  auto planOpen = m_services.planOpen;
  const bool started = m_jobs->start(JobKind::Load, [this, ooc, planOpen, load, inputs, label, budget,
                                                     calibration = offer.folders](ProgressSink& progress,
                                                                                  CancelToken& cancel) {
    if (planOpen) {
      const pipeline::OpenPlan plan = planOpen(inputs, budget, cancel);
      if (plan.mode == pipeline::OpenMode::Refused && !plan.prepared) {
        try {
          return ooc->openRaw(inputs, budget, label, calibration, progress, cancel);
        } catch (const InputError& e) {
          throw InputError(std::string(e.what()) + "; or raise Run > Memory limit…");
        }
      }
      if (plan.mode == pipeline::OpenMode::Refused)
        throw InputError(plan.reason + "; or raise Run > Memory limit…");
      if (plan.mode == pipeline::OpenMode::OutOfCore)
        return ooc->open(inputs, budget, label, plan, progress, cancel);
    }
    if (!load) throwMissingService("FITS reader");
    auto cube = std::make_shared<const FrameCube>(load(inputs, progress, cancel));
    return std::function<void()>([this, cube, label] { m_obs->setRaw(cube, label); });
  });
  if (!started) {
    sayBusy();
    return;
  }
  m_loadingPaths = paths;  // to the recent files once they have opened (onJobFinished)
}

void MainWindow::openDemo() {
  // Nothing changes while another job runs (the grid, the files, the session and the inputs in flight).
  if (m_jobs->busy()) return sayBusy();
  auto simulate = m_services.simulateDemo;
  m_demoGrid = true;
  m_processing->clearFiles();
  m_search->setParams(pipeline::demoSearchParams());  // as synthtrack-cli demo
  m_session->prepareNew({}, true);
  // No load runs, so m_loadingPaths is empty (onJobFinished clears it): the demo has no recent file.
  startLoad("demo observation (simulated paper-neo)",
            [simulate](ProgressSink& progress, CancelToken& cancel) {
              if (!simulate) throwMissingService("simulator");
              return simulate(progress, cancel);
            });
}

void MainWindow::startLoad(const QString& label, std::function<FrameCube(ProgressSink&, CancelToken&)> load) {
  const bool started =
      m_jobs->start(JobKind::Load, [this, load, label](ProgressSink& progress, CancelToken& cancel) {
        auto cube = std::make_shared<const FrameCube>(load(progress, cancel));
        return std::function<void()>([this, cube, label] { m_obs->setRaw(cube, label); });
      });
  if (!started) sayBusy();
}

bool MainWindow::rawIsPrepared() const {
  const auto& raw = m_obs->raw();
  if (!raw) return false;
  try {
    return pipeline::recognisePreparedHeader(raw->header, pipeline::cubeSource(*raw)).has_value();
  } catch (const std::exception&) {
    return true;  // a prepared header that does not add up: running it shows the error
  }
}

void MainWindow::runPreprocess() {
  auto raw = m_obs->raw();
  if (!raw) return;
  if (outOfCore()) {  // a prepared cube, opened as such: nothing to pre-process
    statusBar()->showMessage("Out of core: the cube is pre-processed already and is searched as it is", 10000);
    return;
  }
  auto preprocess = m_services.preprocess;
  auto makeBackend = m_services.makeBackend;
  const auto stages = m_processing->stages();
  const BackendKind kind = m_search->backendKind();
  m_jobs->start(JobKind::Preprocess, [this, raw, preprocess, makeBackend, stages, kind](
                                         ProgressSink& progress, CancelToken& cancel) {
    if (!preprocess) throwMissingService("pre-processing pipeline");
    auto prepared = std::make_shared<const PreparedView>(preprocess(raw, stages, progress, cancel));
    std::string message;
    std::shared_ptr<search::SearchBackend> backend;
    if (makeBackend) backend = makeBackend(kind, message);  // the live-stack backend, its own instance
    return std::function<void()>([this, prepared, backend, message, stages] {
      m_preparedStages = stages;
      m_stackBackend = backend;
      m_scrubber->setBackend(backend);
      if (!message.empty()) m_search->setBackendMessage("stacks: " + QString::fromStdString(message));
      m_obs->setPrepared(prepared);
    });
  });
}

void MainWindow::runSearch() {
  const auto& prepared = m_obs->prepared();
  if (!prepared || !prepared->filtered) return;
  if (outOfCore()) {
    if (!OutOfCoreController::of(this)->runSearch()) sayBusy();
    return;
  }
  auto cube = prepared->filtered;
  auto makeBackend = m_services.makeBackend;
  const search::VelocityGrid grid = m_search->grid();
  const search::SearchParams params = m_search->params();
  const BackendKind kind = m_search->backendKind();
  auto backends = m_searchBackends;
  m_jobs->start(JobKind::Search, [this, cube, makeBackend, backends, grid, params, kind](
                                     ProgressSink& progress, CancelToken& cancel) {
    if (!makeBackend) throwMissingService("search backend");
    std::string message;
    auto result =
        backends->with(kind, makeBackend, [&](search::SearchBackend& backend, const std::string& m) {
          message = m;
          return std::make_shared<const search::SearchResult>(
              search::searchWithMethod(backend, *cube, grid, params, progress, cancel));
        });
    return std::function<void()>([this, result, message] {
      m_search->setBackendMessage(QString::fromStdString(message));
      m_obs->setResult(result);
      statusBar()->showMessage(QString("Search: %1 in %2 s (%3)")
                                   .arg(candidateSummary(*result))
                                   .arg(result->elapsedS, 0, 'f', 1)
                                   .arg(QString::fromStdString(std::string(result->method.name()) + " on " +
                                                               result->backend)),
                               15000);
      if (!result->candidates.empty()) selectCandidate(0);
    });
  });
}

void MainWindow::onJobFinished(JobKind kind, bool ok, bool cancelled, const QString& message,
                               double elapsedS) {
  const QString name = jobName(kind);
  m_progress->hide();
  m_cancel->hide();
  m_processing->setRunEnabled(m_obs->raw() != nullptr);
  m_search->setRunning(false);
  if (m_cancelQuestion) m_cancelQuestion->close();
  if (cancelled) {
    m_jobLabel->setText(name + " cancelled");
    if (kind == JobKind::Search)
      m_search->setStatusText(QString("Search cancelled after %1 s%2")
                                  .arg(elapsedS, 0, 'f', 1)
                                  .arg(m_obs->result() ? "; the previous result is shown" : ""));
  } else if (!ok) {
    m_jobLabel->setText(name + " failed");
    // A file that would not open says why in the central view too (the status bar's line is cut short and
    // gone after 10 s; a scripted run shows no dialog), and stays out of the recent files.
    if (kind == JobKind::Load && !m_obs->raw())
      m_view->setPlaceholder(
          (m_loadingPaths.isEmpty() ? QString("Could not open the demo observation:\n")
                                    : "Could not open " + m_loadingPaths.join(", ") + ":\n") +
          message + "\n\n" + ImageView::defaultPlaceholder());
    if (kind == JobKind::PlateSolve)  // the WCS banner keeps the message, with "Try again" and "Settings…"
      statusBar()->showMessage(name + " failed: " + message, 20000);
    else
      showError(name + " failed", message);
  } else {
    m_jobLabel->setText(QString("%1 done in %2 s").arg(name).arg(elapsedS, 0, 'f', 1));
  }
  // A cube written by `synthtrack-cli preprocess` opens as prepared whatever the setting: the service takes
  // its header's PSF, noise and sky rate and does not run the pipeline on it again.
  // Out of core it is opened pre-processed already.
  if (ok && kind == JobKind::Load) {
    if (!m_loadingPaths.isEmpty()) addRecent(m_loadingPaths);
    m_view->setPlaceholder(ImageView::defaultPlaceholder());
  }
  if (kind == JobKind::Load) m_loadingPaths.clear();
  if (ok && kind == JobKind::Load && !outOfCore() && (m_autoPreprocess || rawIsPrepared())) runPreprocess();
}

void MainWindow::onRawChanged() {
  const auto& raw = m_obs->raw();
  setWindowTitle(raw ? "synthtrack — " + m_obs->label() : QString("synthtrack"));
  m_processing->setRunEnabled(raw != nullptr);
  m_search->setReady(false);
  if (raw) {
    m_frameSpin->setRange(0, static_cast<int>(raw->frameCount()) - 1);
    m_frameSpin->setSuffix(QString(" / %1").arg(raw->frameCount()));
    m_search->setDefaultsFor(*raw, {});
    if (rawIsPrepared()) m_processing->clearOffer();  // calibrated already: nothing to offer
    QString summary = QString("%1 frames of %2 × %3 px, %4 s")
                          .arg(raw->frameCount())
                          .arg(raw->width())
                          .arg(raw->height())
                          .arg(raw->timeSpanS(), 0, 'f', 1);
    if (raw->plateScaleArcsecPerPx)
      summary += QString(", %1\"/px").arg(*raw->plateScaleArcsecPerPx, 0, 'f', 3);
    for (const auto& w : raw->warnings)
      summary += "\n⚠ " + QString::fromStdString(w);
    m_processing->setSummary(summary);
  }
  refreshSourceList();
  showSource(Source::RawFrame);
}

void MainWindow::onPreparedChanged() {
  const auto& prepared = m_obs->prepared();
  m_search->setReady(prepared && prepared->filtered);
  if (prepared) {
    m_processing->setSummary(QString::fromStdString(prepared->summary));
    if (rawIsPrepared() && prepared->outOfCore.empty())
      statusBar()->showMessage("Opened as a prepared cube (written by synthtrack-cli preprocess): not "
                               "pre-processed again; PSF, sky rate and noise from its header",
                               20000);
    if (prepared->filtered && m_obs->raw()) {
      m_search->setDefaultsFor(prepared->filtered->frames, prepared->filtered->skyRate);
      const auto& raw = *m_obs->raw();
      if (m_demoGrid && raw.plateScaleArcsecPerPx) {
        // The demo's grid, made as `synthtrack-cli demo` makes it (st/pipeline/demo_search.hpp).
        try {
          m_search->setGrid(search::makeVelocityGrid(pipeline::demoGridSpec(raw.plateScaleArcsecPerPx),
                                                     *prepared->filtered),
                            QString("the demo's grid: ±%1 deg/day in %2 px steps (as synthtrack-cli demo; "
                                    "the paper's, for other observations: ±12 deg/day in 1 px steps)")
                                .arg(search::kDemoHalfRangeDegPerDay)
                                .arg(search::kDemoGridStepPx));
        } catch (const std::exception& e) {  // the paper's grid stays
          statusBar()->showMessage("Demo grid not set: " + QString::fromStdString(e.what()), 10000);
        }
      }
      m_obs->setVelocity(prepared->filtered->skyRate);
    }
  }
  refreshSourceList();
  // Out of core the view keeps the mean of all frames (a stack is a pass over the whole file).
  if (outOfCore())
    showSource(Source::RawFrame);
  else if (prepared && prepared->filtered)
    showSource(Source::Stack);
}

bool MainWindow::outOfCore() const {
  const auto& prepared = m_obs->prepared();
  return prepared && !prepared->outOfCore.empty();
}

void MainWindow::selectCandidate(int index) {
  const auto& result = m_obs->result();
  if (!result || index < 0 || index >= static_cast<int>(result->candidates.size())) return;
  m_obs->setSelected(index);
}

void MainWindow::onSelection() {
  const search::Candidate* c = m_obs->selectedCandidate();
  updateMarkers();
  if (!c) return;
  m_obs->setVelocity(c->v);
  showSource(Source::Stack);
  m_view->centreOn(c->x, c->y);
}

}  // namespace st::ui

#include "script_runner.hpp"

#include <QApplication>
#include <QDialog>
#include <QDockWidget>
#include <QFileInfo>
#include <QStatusBar>
#include <QTimer>
#include <algorithm>
#include <cstdio>
#include <memory>

#include "calibration_files.hpp"
#include "figure_dialog.hpp"
#include "plate_solve_settings.hpp"
#include "fit_panel.hpp"
#include "job_runner.hpp"
#include "main_window.hpp"
#include "processing_panel.hpp"
#include "report_dialog.hpp"
#include "search_panel.hpp"
#include "session_controller.hpp"
#include "st/common/error.hpp"
#include "st/report/submission_settings.hpp"

namespace st::ui {
namespace {

// Connects `signal` of `sender` for one emission only.
template <typename Sender, typename Signal, typename Slot>
void once(Sender* sender, Signal signal, QObject* context, Slot slot) {
  auto connection = std::make_shared<QMetaObject::Connection>();
  *connection = QObject::connect(sender, signal, context, [connection, slot](auto&&... args) {
    QObject::disconnect(*connection);
    slot(args...);
  });
}

}  // namespace

ScriptRunner::ScriptRunner(MainWindow* window) : QObject(window), m_window(window) {
  // After the window's own handling of the job (connected in its constructor): a finished load has started
  // the pre-processing already when the window does that by itself.
  connect(window->jobs(), &JobRunner::finished, this,
          [this](JobKind kind, bool ok, bool cancelled, const QString& message, double) {
            onJobFinished(kind, ok, cancelled, message);
          });
}

void ScriptRunner::run(const ScriptOptions& options) {
  m_script = options;
  m_window->setScripted(true);
  if (!options.solveField.isEmpty() || !options.indexDirs.isEmpty()) {
    PlateSolveSettings settings = PlateSolveSettings::load();
    if (!options.solveField.isEmpty()) settings.solveField = options.solveField;
    if (!options.indexDirs.isEmpty()) settings.indexDirs = options.indexDirs;
    settings.save();
  }
  if (!options.session.isEmpty())
    m_window->openSession(options.session);
  else if (options.demo)
    m_window->openDemo();
  else if (!options.inputs.isEmpty())
    openInputs(options);
  else
    QTimer::singleShot(300, this, [this] { finish(true, {}); });
}

void ScriptRunner::onJobFinished(JobKind kind, bool ok, bool cancelled, const QString& message) {
  if (!m_script) return;
  if (ok && !cancelled) advance(kind);
  if (!ok && !cancelled) finish(false, message);
}

void ScriptRunner::openInputs(const ScriptOptions& options) {
  m_window->openInputs(options.inputs);
  ProcessingPanel* processing = m_window->processingPanel();
  if (options.noCalibrationOffer) processing->clearOffer();
  const std::pair<const char*, const QStringList*> given[] = {
      {kBiasFiles, &options.bias}, {kFlatFiles, &options.flat}, {kDarkFiles, &options.dark}};
  for (const auto& [key, paths] : given) {
    if (paths->isEmpty()) continue;
    QStringList absolute;
    for (const QString& p : *paths)
      absolute << QFileInfo(p).absoluteFilePath();
    processing->setFiles(key, absolute);
  }
}

void ScriptRunner::printCalibration() {
  const ProcessingPanel* processing = m_window->processingPanel();
  if (!processing->offerNote().isEmpty())
    std::printf("calibration: %s\n", processing->offerNote().toLocal8Bit().constData());
  for (const char* key : {kBiasFiles, kFlatFiles, kDarkFiles}) {
    const QStringList files = processing->files(key);
    if (!files.isEmpty())
      std::printf("calibration %s: %s\n", key, files.join("; ").toLocal8Bit().constData());
  }
  std::fflush(stdout);
}

void ScriptRunner::advance(JobKind finished) {
  const ScriptOptions& script = *m_script;
  if (finished == JobKind::OpenSession) {  // restored without searching again
    if (script.select) m_window->selectCandidate(*script.select - 1);
    finish(true, {});
    return;
  }
  if (finished == JobKind::Load) printCalibration();  // as loaded (a prepared cube drops the offer)
  if (finished == JobKind::Load && !m_window->autoPreprocess() && !m_window->rawIsPrepared())
    m_window->runPreprocess();
  const SearchPanel* search = m_window->searchPanel();
  if (finished == JobKind::Preprocess) {
    // Scripted runs say what pre-processing did (calibration, PSF, sky rate) and the grid the search takes.
    if (const auto& prepared = m_window->observation()->prepared())
      std::printf("pre-processing: %s\n", prepared->summary.c_str());
    const QString status = m_window->statusBar()->currentMessage();
    if (status.startsWith("Opened as a prepared cube"))
      std::printf("status: %s\n", status.toLocal8Bit().constData());
    std::printf("grid: %s\nestimate: %s\n", search->gridOrigin().toLocal8Bit().constData(),
                search->estimateText().toLocal8Bit().constData());
    std::fflush(stdout);
    const auto& raw = m_window->observation()->raw();
    if (script.plateSolve && raw && !raw->wcs) {
      if (!m_window->runPlateSolve()) finish(false, "plate solving could not start");
      return;
    }
    searchOrFinish();
  }
  if (finished == JobKind::PlateSolve) {
    std::printf("plate solve: %s\n", m_window->plateSolveSummary().toLocal8Bit().constData());
    std::fflush(stdout);
    searchOrFinish();
  }
  if (finished == JobKind::Search) {
    // Scripted runs list the candidates on stdout, so a figure's --select N can be chosen reproducibly.
    const auto& result = m_window->observation()->result();
    for (std::size_t i = 0; result && i < result->candidates.size(); ++i) {
      const auto& c = result->candidates[i];
      std::printf("candidate %zu: x %d y %d vx %.4f vy %.4f px/s snr %.2f fap %.3g n_in %d\n", i + 1, c.x,
                  c.y, c.v.vx, c.v.vy, c.snr, c.fap, c.nIn);
    }
    std::printf("search: %s\n", search->statusText().toLocal8Bit().constData());
    std::fflush(stdout);
    if (script.select) m_window->selectCandidate(*script.select - 1);
    if (script.fit && m_window->observation()->selectedCandidate()) return runFit();
    finish(true, {});
  }
}

void ScriptRunner::searchOrFinish() {
  if (m_script->search)
    m_window->runSearch();
  else
    finish(true, {});
}

void ScriptRunner::runFit() {
  FitPanel* fit = m_window->fitPanel();
  auto* conn = new QMetaObject::Connection;
  *conn = connect(fit, &FitPanel::fitFinished, this,
                  [this, conn](bool ok, bool cancelled, const QString& message) {
                    disconnect(*conn);
                    delete conn;
                    finish(ok && !cancelled, message);
                  });
  for (QDockWidget* d : m_window->findChildren<QDockWidget*>())
    if (d->widget() == fit) d->raise();
  fit->fitSelected();
  if (fit->running()) return;
  disconnect(*conn);
  delete conn;
  finish(false, "the co-moving fit could not start: " + fit->statusText());
}

void ScriptRunner::finish(bool ok, const QString& message) {
  if (!m_script) return;
  const ScriptOptions script = *m_script;
  if (!ok) std::fprintf(stderr, "synthtrack: %s\n", message.toLocal8Bit().constData());
  // Let the live stack arrive and the widgets lay out before the picture is taken.
  QTimer::singleShot(1200, this, [this, script, ok] {
    runExports(script, [this, script, ok](bool exportsOk) {
      bool good = ok && exportsOk;
      if (!script.screenshot.isEmpty())
        good =
            m_window->saveScreenshot(script.screenshot, script.screenshotWidth, script.screenshotColours) &&
            good;
      if (m_window->lastStackLatencyMs() > 0)
        std::printf("live stack: %.0f ms from request to image\n", m_window->lastStackLatencyMs());
      if (const auto& ro = m_window->session()->readOnly())  // a scripted run says what the banner says
        std::printf("session read-only: %s is open in %s; %d change(s) made here are not saved\n",
                    ro->path.toLocal8Bit().constData(), ro->holder.toLocal8Bit().constData(),
                    ro->unsavedChanges);
      std::fflush(stdout);
      m_script.reset();
      m_window->setScripted(false);
      emit finished(good);
      if (script.quit || !script.screenshot.isEmpty()) QApplication::exit(good ? 0 : 1);
    });
  });
}

bool ScriptRunner::applyVetting(const ScriptOptions& script) {
  if (script.acceptFit) m_window->fitPanel()->accept();
  Observation* obs = m_window->observation();
  for (const QString& entry : script.labels) {
    const auto eq = entry.indexOf('=');
    bool number = false;
    const int n = entry.left(eq).toInt(&number);
    try {
      if (eq < 0 || !number || !obs->candidateState(n - 1))
        throw InputError("--label needs N=LABEL with N a candidate number, got '" + entry.toStdString() +
                         "'");
      const QStringList parts = entry.mid(eq + 1).split(':');
      const session::Label label = session::labelFromString(parts[0].toStdString());
      const session::ArtifactReason reason = parts.size() > 1
                                                 ? session::reasonFromString(parts[1].toStdString())
                                                 : session::ArtifactReason::None;
      obs->setCandidateLabel(n - 1, label, reason);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "synthtrack: %s\n", e.what());
      return false;
    }
  }
  return true;
}

void ScriptRunner::runExports(const ScriptOptions& script, std::function<void(bool ok)> done) {
  auto ok = std::make_shared<bool>(applyVetting(script));
  auto showDialog = [this, script, done, ok] {
    if (script.dialog.isEmpty()) return done(*ok);
    if (script.dialog != "figure" && script.dialog != "reports") {
      std::fprintf(stderr, "synthtrack: --dialog takes figure or reports, got '%s'\n",
                   qPrintable(script.dialog));
      return done(false);
    }
    QDialog* d = script.dialog == "figure" ? static_cast<QDialog*>(m_window->figureDialog())
                                           : m_window->reportDialog();
    d->show();
    d->adjustSize();
    m_window->setScreenshotOverlay(d);
    QTimer::singleShot(300, this, [done, ok] { done(*ok); });
  };
  auto report = [ok](const char* what, bool good, const QString& message) {
    std::printf("%s: %s\n", what, qPrintable(message));
    std::fflush(stdout);
    *ok = *ok && good;
  };
  auto reports = [this, script, showDialog, report] {
    if (script.exportReports.isEmpty()) return showDialog();
    ReportDialog* r = m_window->reportDialog();
    r->setOutput(script.exportReports, "synthtrack");
    // ADES and MPC 80-column too when a candidate is labelled real and a station is set; settings that would
    // not make a valid file are named (the other reports are still written).
    const report::SubmissionSettings settings = r->submissionSettings();
    const auto& states = m_window->observation()->candidateStates();
    // A real candidate with a converged fit that has a sky position, as report::realDetections takes them.
    const bool submit = !settings.stationCode.empty() &&
                        std::any_of(states.begin(), states.end(), [](const auto& s) {
                          return s.label == session::Label::Real && s.fitted() && s.fit->sky;
                        });
    bool ades = false, mpc = false;
    if (submit) {
      const auto adesProblems = report::submissionProblems(settings, report::SubmissionFormat::Ades);
      const auto mpcProblems = report::submissionProblems(settings, report::SubmissionFormat::Mpc80);
      ades = adesProblems.empty();
      mpc = mpcProblems.empty();
      if (!ades)
        std::printf("reports: no ADES file: %s\n",
                    report::problemsText(adesProblems, report::SubmissionFormat::Ades).c_str());
      if (!mpc)
        std::printf("reports: no MPC 80-column file: %s\n",
                    report::problemsText(mpcProblems, report::SubmissionFormat::Mpc80).c_str());
    }
    r->setOutputs(true, true, true, false, ades, mpc);
    once(r, &ReportDialog::exportFinished, this, [=](bool good, const QString& message) {
      report("reports", good, message);
      showDialog();
    });
    r->exportReports();  // emits exportFinished, also when it cannot start
  };
  if (script.exportFigure.isEmpty()) return reports();
  FigureDialog* f = m_window->figureDialog();
  f->refreshSources();
  f->setSource(m_window->observation()->selectedCandidate() ? f->presetIndex() : 0);
  f->setFigureSize({7.0, 0.0, static_cast<double>(script.figureDpi)});
  once(f, &FigureDialog::exportFinished, this, [=](const QString&, bool good, const QString& message) {
    report("figure", good, message);
    reports();
  });
  f->exportTo(script.exportFigure);  // emits exportFinished, also when it cannot start
}

}  // namespace st::ui

// MainWindow: the session file (issue 8 §6). Every change autosaves through SessionController; File >
// New/Open session…, Save session as… and the recent sessions; reopening a session reloads and pre-processes
// its inputs in a worker, then puts the saved result and vetting back without searching again.
#include <QFileDialog>
#include <QVBoxLayout>
#include <QPushButton>
#include <QHBoxLayout>
#include <QFrame>
#include <QFileInfo>
#include <QLabel>
#include <QMenu>
#include <QMessageBox>
#include <QSettings>
#include <QStatusBar>
#include <QTimer>
#include <filesystem>

#include "eliding_label.hpp"
#include "job_runner.hpp"
#include "out_of_core_controller.hpp"
#include "main_window.hpp"
#include "processing_panel.hpp"
#include "search_panel.hpp"
#include "session_controller.hpp"
#include "st/pipeline/plate_solve_stage.hpp"
#include "stack_scrubber.hpp"

namespace st::ui {
namespace {

/// Inputs as the session names them; a relative path that does not exist from the working folder is taken
/// relative to the session file's folder (sessions written by `synthtrack-cli` keep the paths as given).
std::vector<std::string> resolveInputs(std::vector<std::string> inputs, const std::string& sessionFile) {
  namespace fs = std::filesystem;
  const fs::path base = fs::path(sessionFile).parent_path();
  for (auto& in : inputs) {
    std::error_code ec;
    if (fs::path(in).is_relative() && !fs::exists(in, ec) && fs::exists(base / in, ec))
      in = (base / in).lexically_normal().string();
  }
  return inputs;
}

}  // namespace

/// What the "Opening session" job hands to the GUI thread.
struct OpenedSession {
  QString path;
  SessionSnapshot snapshot;
  std::int64_t changes = 0;
  nlohmann::json settings;
  std::shared_ptr<const FrameCube> raw;
  std::shared_ptr<const PreparedView> prepared;
  std::shared_ptr<search::SearchBackend> backend;
  std::string backendMessage;
};

void MainWindow::buildSession() {
  m_session = new SessionController(
      m_obs,
      [this] {
        SessionParameters p;
        // The stages the current cube was made with (the panel may have been edited since).
        p.stages = m_obs->prepared() && !m_preparedStages.empty() ? m_preparedStages : m_processing->stages();
        p.grid = m_search->grid();
        p.search = m_search->params();
        p.backend = m_search->backendKind();
        return p;
      },
      this);
  // The search panel's settings are part of the session: a change by hand is saved like a label.
  connect(m_search, &SearchPanel::settingsChanged, m_session, &SessionController::requestSave);
  // Elided in the middle where the window is narrow (a long path must not widen it past a laptop screen).
  m_sessionLabel = new ElidingLabel("Session: none", 160, 520, this);
  connect(m_session, &SessionController::statusChanged, this,
          [this](const QString& text, const QString& tooltip, bool error) {
            m_sessionLabel->setText(text);
            m_sessionLabel->setToolTip(text + "\n" + tooltip);
            m_sessionLabel->setStyleSheet(error ? "color: #c00000; font-weight: bold" : QString());
          });
  connect(m_session, &SessionController::pathChanged, this, &MainWindow::addRecentSession);
  buildReadOnlyBanner();
  connect(m_session, &SessionController::notice, this, [this](const QString& text) {
    // After the job's own message (a search reports its result just after setResult).
    QTimer::singleShot(0, this, [this, text] { statusBar()->showMessage(text, 20000); });
  });
  connect(m_session, &SessionController::saveFailed, this, [this](const QString& message) {
    statusBar()->showMessage(message, 15000);
    if (m_scripted || m_session->readOnly()) return;  // read-only: the banner says it, without a dialog
    auto* box = new QMessageBox(QMessageBox::Warning, "Session not saved", message, QMessageBox::Ok, this);
    box->setAttribute(Qt::WA_DeleteOnClose);
    box->setModal(false);  // the GUI goes on; the next change tries again
    box->show();
  });
}

void MainWindow::buildReadOnlyBanner() {
  // Above the image, where it cannot be missed: this window shows a session another window writes.
  m_readOnlyBanner = new QFrame(centralWidget());
  m_readOnlyBanner->setObjectName("session.readOnlyBanner");
  m_readOnlyBanner->setStyleSheet(
      "#session\\.readOnlyBanner { background: #fff3c4; border-bottom: 1px solid #d4a000; } QLabel { color: #5a4200; }");
  auto* text = new QLabel(m_readOnlyBanner);
  text->setObjectName("session.readOnlyText");
  text->setWordWrap(true);
  auto* saveCopy = new QPushButton("Save a copy as…", m_readOnlyBanner);
  saveCopy->setToolTip("Save this window's state, with the changes made here, to another session file "
                       "(it is then saved there after every change)");
  auto* row = new QHBoxLayout(m_readOnlyBanner);
  row->setContentsMargins(8, 4, 8, 4);
  row->addWidget(text, 1);
  row->addWidget(saveCopy);
  if (auto* layout = qobject_cast<QVBoxLayout*>(centralWidget()->layout())) layout->insertWidget(0, m_readOnlyBanner);
  m_readOnlyBanner->hide();
  connect(saveCopy, &QPushButton::clicked, this, &MainWindow::saveSessionCopy);
  connect(m_session, &SessionController::readOnlyChanged, this, [this, text] {
    const auto& ro = m_session->readOnly();
    m_readOnlyBanner->setVisible(ro.has_value());
    if (!ro) return;
    QString line = QString("<b>Read-only:</b> this session is open in %1 (%2). Labels, notes and fits made "
                           "here are not saved to it")
                       .arg(ro->holder.toHtmlEscaped(), ro->path.toHtmlEscaped());
    if (ro->unsavedChanges > 0)
      line += QString(" — <b>%1 unsaved change%2</b>: save a copy to keep them")
                  .arg(ro->unsavedChanges)
                  .arg(ro->unsavedChanges == 1 ? "" : "s");
    text->setText(line + ".");
  });
}

bool MainWindow::saveSessionCopy() {
  const QString suggested = freeSessionPath(m_session->readOnly() ? m_session->readOnly()->path : m_session->path());
  const QString path = QFileDialog::getSaveFileName(this, "Save a copy of the session", suggested,
                                                    "synthtrack sessions (*.json)");
  if (path.isEmpty()) return false;
  m_session->saveAs(path);
  return !m_session->readOnly();
}

bool MainWindow::confirmCloseReadOnly() {
  const auto& ro = m_session->readOnly();
  if (m_scripted || !ro || ro->unsavedChanges == 0) return true;
  QMessageBox box(QMessageBox::Warning, "Unsaved changes",
                  QString("This window showed %1 read-only (it is open in %2). %3 change%4 made here "
                          "(labels, notes, fits) are in no file.")
                      .arg(ro->path, ro->holder)
                      .arg(ro->unsavedChanges)
                      .arg(ro->unsavedChanges == 1 ? " was" : "s were"),
                  QMessageBox::Save | QMessageBox::Discard | QMessageBox::Cancel, this);
  box.setObjectName("session.unsavedQuestion");
  box.button(QMessageBox::Save)->setText("Save a copy as…");
  box.setDefaultButton(QMessageBox::Save);
  switch (box.exec()) {
    case QMessageBox::Discard:
      return true;
    case QMessageBox::Save:
      return saveSessionCopy();
    default:
      return false;
  }
}

void MainWindow::buildSessionMenu(QMenu* file) {
  file->addSeparator();
  file->addAction("&New session for this observation", this,
                  [this] {
                    if (m_session->demo()) {
                      openDemo();
                    } else if (!m_session->inputs().empty()) {
                      QStringList paths;
                      for (const auto& p : m_session->inputs())
                        paths << QString::fromStdString(p);
                      openInputs(paths);
                    }
                  })
      ->setToolTip("Reopen the observation in a new session file (the current file is kept)");
  file->addAction("Open sess&ion…", QKeySequence("Ctrl+Shift+S"), this, [this] {
    const QString path =
        QFileDialog::getOpenFileName(this, "Open session", QFileInfo(m_session->path()).path(),
                                     "synthtrack sessions (*.json);;All files (*)");
    if (!path.isEmpty()) openSession(path);
  });
  file->addAction("Save session &as…", this, [this] {
    const QString path = QFileDialog::getSaveFileName(this, "Save session as", m_session->path(),
                                                      "synthtrack sessions (*.json)");
    if (!path.isEmpty()) m_session->saveAs(path);
  });
  m_recentSessionsMenu = file->addMenu("Recent sess&ions");
}

void MainWindow::addRecentSession(const QString& path) {
  QSettings settings;
  QStringList recent = settings.value("recentSessions").toStringList();
  recent.removeAll(path);
  recent.prepend(path);
  while (recent.size() > 10)
    recent.removeLast();
  settings.setValue("recentSessions", recent);
  rebuildRecentSessionsMenu();
}

void MainWindow::rebuildRecentSessionsMenu() {
  if (!m_recentSessionsMenu) return;
  m_recentSessionsMenu->clear();
  const QStringList recent = QSettings().value("recentSessions").toStringList();
  for (int i = 0; i < recent.size(); ++i) {
    const QString path = recent[i];
    // Gone: a pruned demo autosave or a file moved away (the newest is the current one, maybe not yet
    // written).
    if (i > 0 && !QFileInfo::exists(path)) continue;
    m_recentSessionsMenu->addAction(QFileInfo(path).fileName(), this, [this, path] { openSession(path); })
        ->setToolTip(path);
  }
  m_recentSessionsMenu->setEnabled(!m_recentSessionsMenu->isEmpty());
}

void MainWindow::openSession(const QString& path) {
  auto load = m_services.loadFrames;
  auto simulate = m_services.simulateDemo;
  auto preprocess = m_services.preprocess;
  auto makeBackend = m_services.makeBackend;
  const auto defaults = m_services.preprocessStages;
  const BackendKind kind = m_search->backendKind();
  const std::string file = QFileInfo(path).absoluteFilePath().toStdString();
  auto planOpen = m_services.planOpen;
  const std::size_t budget = OutOfCoreController::of(this)->budget().bytes;
  const bool started =
      m_jobs->start(JobKind::OpenSession, [=, this](ProgressSink& progress, CancelToken& cancel) {
        auto opened = std::make_shared<OpenedSession>();
        opened->path = QString::fromStdString(file);
        // A corrupted or newer file throws here, after SessionStore copied it aside; the message names the
        // copy.
        const session::Session s = session::SessionStore(file).load();
        opened->snapshot = restoreSnapshot(s, defaults, file);
        opened->snapshot.inputs = resolveInputs(opened->snapshot.inputs, file);
        opened->changes = s.changes;
        opened->settings = s.settings;
        const auto& snap = opened->snapshot;
        FrameCube raw;
        if (snap.parameters.demo) {
          if (!simulate) throwMissingService("simulator");
          raw = simulate(progress, cancel);
        } else {
          if (!load) throwMissingService("FITS reader");
          if (snap.inputs.empty()) throw InputError("session '" + file + "' names no input files");
          // A cube over the memory budget is never loaded whole (issue 20): sessions reopen in memory only.
          if (planOpen && planOpen(snap.inputs, budget, cancel).mode != pipeline::OpenMode::InMemory)
            throw InputError("the inputs of session '" + file + "' are larger than the memory budget of " +
                             formatBytes(static_cast<double>(budget)) +
                             ": a session reopens in memory only; open the cube with File > Open (a "
                             "pre-processed cube opens out of core) or raise Run > Memory limit…");
          raw = load(snap.inputs, progress, cancel);
        }
        // The WCS plate-solved for these frames when the session was made: pre-processing carries it as a
        // header WCS, as after "Plate solve" (frames that have a WCS of their own by now keep theirs).
        if (snap.solvedWcs && !raw.wcs)
          pipeline::attachHeaderWcs(raw, snap.solvedWcs->wcs, snap.solvedWcs->plateScaleArcsecPerPx);
        opened->raw = std::make_shared<const FrameCube>(std::move(raw));
        if (!preprocess) throwMissingService("pre-processing pipeline");
        opened->prepared = std::make_shared<const PreparedView>(
            preprocess(opened->raw, snap.parameters.stages, progress, cancel));
        if (makeBackend) opened->backend = makeBackend(kind, opened->backendMessage);
        return std::function<void()>([this, opened] { applyOpenedSession(*opened); });
      });
  if (!started) sayBusy();
}

void MainWindow::applyOpenedSession(const OpenedSession& opened) {
  const SessionSnapshot& snap = opened.snapshot;
  // Nothing is saved while the state is rebuilt: the file already holds it.
  m_session->setSuspended(true);
  m_session->adopt(opened.path, snap.inputs, snap.parameters.demo, opened.changes, opened.settings,
                   snap.parameters.demoAutosave);
  m_demoGrid = snap.parameters.demo;
  m_processing->setStages(snap.parameters.stages);
  m_preparedStages = snap.parameters.stages;
  QString label = snap.label;
  if (label.isEmpty()) label = QFileInfo(opened.path).fileName();
  m_obs->setRaw(opened.raw, label);
  m_stackBackend = opened.backend;
  m_scrubber->setBackend(opened.backend);
  if (!opened.backendMessage.empty())
    m_search->setBackendMessage("stacks: " + QString::fromStdString(opened.backendMessage));
  m_obs->setPrepared(opened.prepared);
  // Recorded as solved again (saved with the session from now on), the banner hidden.
  if (snap.solvedWcs && opened.raw && opened.raw->wcs == snap.solvedWcs->wcs)
    m_obs->attachWcs(snap.solvedWcs->wcs, snap.solvedWcs->plateScaleArcsecPerPx);
  // The search panel as it was saved: unit, grid (exactly), threshold, method, backend.
  if (snap.unitSaved) {
    m_search->setUnit(snap.unit);
    m_obs->setUnit(snap.unit);
  }
  const search::VelocityGrid& g = snap.parameters.grid;
  if (g.count() > 0 && g.stepPxS > 0.0) m_search->setGrid(g, "restored from the session");
  m_search->setParams(snap.parameters.search);
  m_search->setBackendKind(snap.parameters.backend);
  int vetted = 0;
  if (snap.result) {
    m_obs->setResult(snap.result, snap.states);
    for (const auto& s : snap.states)
      vetted += s.label != session::Label::Unvetted ? 1 : 0;
    if (snap.selected) selectCandidate(*snap.selected);
  }
  m_session->setSuspended(false);
  statusBar()->showMessage(QString("Session restored from %1: %2 candidates, %3 vetted (not searched again)")
                               .arg(opened.path)
                               .arg(snap.result ? snap.result->candidates.size() : 0)
                               .arg(vetted),
                           15000);
}

}  // namespace st::ui

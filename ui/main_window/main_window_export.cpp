// MainWindow: the Export menu (figures and reports). The dialogs do the work in workers.
#include <QMenu>
#include <QTimer>
#include <algorithm>
#include <cstdio>

#include "figure_dialog.hpp"
#include "fit_panel.hpp"
#include "inspector_panel.hpp"
#include "main_window.hpp"
#include "report_dialog.hpp"
#include "session_controller.hpp"
#include "st/common/error.hpp"
#include "st/report/submission_settings.hpp"

namespace st::ui {

void MainWindow::buildExportMenu(QMenu* menu) {
  menu->addAction("Export &figure…", QKeySequence("Ctrl+E"), this, [this] {
    FigureDialog* d = figureDialog();
    d->show();
    d->raise();
  });
  menu->addAction("&Reports (CSV, JSON, DS9, FITS, ADES, MPC)…", QKeySequence("Ctrl+Shift+E"), this, [this] {
    ReportDialog* d = reportDialog();
    d->show();
    d->raise();
  });
}

FigureDialog* MainWindow::figureDialog() {
  if (!m_figureDialog) {
    FigureDialog::Context ctx;
    ctx.observation = m_obs;
    ctx.root = this;
    ctx.central = m_view;
    ctx.stackCube = [this] { return m_inspector->stackCube(); };
    ctx.pixelToSky = m_services.pixelToSky;
    m_figureDialog = new FigureDialog(std::move(ctx), this);
  }
  return m_figureDialog;
}

ReportDialog* MainWindow::reportDialog() {
  if (!m_reportDialog) {
    ReportDialog::Context ctx;
    ctx.observation = m_obs;
    // The same record the session file keeps, with the dialog's report settings.
    ctx.makeSession = [this](const nlohmann::json& settings) {
      session::Session s = m_session->currentSession();
      s.settings = settings;
      return s;
    };
    m_reportDialog = new ReportDialog(std::move(ctx), this);
    // A session's own settings win over those remembered in QSettings (a reopened session keeps its station);
    // edits go into the session (and autosave).
    const auto adopt = [this] {
      if (m_session->settings().contains("station"))
        m_reportDialog->setSubmissionSettings(report::submissionFromJson(m_session->settings()));
    };
    adopt();
    connect(m_session, &SessionController::pathChanged, m_reportDialog, adopt);
    connect(m_reportDialog, &ReportDialog::settingsChanged, this, [this](const nlohmann::json& settings) {
      if (settings != m_session->settings()) m_session->setSettings(settings);
    });
  }
  return m_reportDialog;
}

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

bool MainWindow::applyScriptVetting(const ScriptOptions& script) {
  if (script.acceptFit) m_fitPanel->accept();
  for (const QString& entry : script.labels) {
    const auto eq = entry.indexOf('=');
    bool number = false;
    const int n = entry.left(eq).toInt(&number);
    try {
      if (eq < 0 || !number || !m_obs->candidateState(n - 1))
        throw InputError("--label needs N=LABEL with N a candidate number, got '" + entry.toStdString() +
                         "'");
      const QStringList parts = entry.mid(eq + 1).split(':');
      const session::Label label = session::labelFromString(parts[0].toStdString());
      const session::ArtifactReason reason = parts.size() > 1
                                                 ? session::reasonFromString(parts[1].toStdString())
                                                 : session::ArtifactReason::None;
      m_obs->setCandidateLabel(n - 1, label, reason);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "synthtrack: %s\n", e.what());
      return false;
    }
  }
  return true;
}

void MainWindow::runScriptExports(const ScriptOptions& script, std::function<void(bool ok)> done) {
  auto ok = std::make_shared<bool>(applyScriptVetting(script));
  auto showDialog = [this, script, done, ok] {
    if (script.dialog.isEmpty()) return done(*ok);
    if (script.dialog != "figure" && script.dialog != "reports") {
      std::fprintf(stderr, "synthtrack: --dialog takes figure or reports, got '%s'\n",
                   qPrintable(script.dialog));
      return done(false);
    }
    QDialog* d = script.dialog == "figure" ? static_cast<QDialog*>(figureDialog()) : reportDialog();
    d->show();
    d->adjustSize();
    m_screenshotOverlay = d;
    QTimer::singleShot(300, this, [done, ok] { done(*ok); });
  };
  auto report = [ok](const char* what, bool good, const QString& message) {
    std::printf("%s: %s\n", what, qPrintable(message));
    std::fflush(stdout);
    *ok = *ok && good;
  };
  auto reports = [this, script, showDialog, report] {
    if (script.exportReports.isEmpty()) return showDialog();
    ReportDialog* r = reportDialog();
    r->setOutput(script.exportReports, "synthtrack");
    // ADES and MPC 80-column too when a candidate is labelled real and a station is set; settings that would
    // not make a valid file are named (the other reports are still written).
    const report::SubmissionSettings settings = r->submissionSettings();
    const auto& states = m_obs->candidateStates();
    const bool submit = !settings.stationCode.empty() &&
                        std::any_of(states.begin(), states.end(),
                                    [](const auto& s) { return s.label == session::Label::Real; });
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
  FigureDialog* f = figureDialog();
  f->refreshSources();
  f->setSource(m_obs->selectedCandidate() ? f->presetIndex() : 0);
  f->setFigureSize({7.0, 0.0, static_cast<double>(script.figureDpi)});
  once(f, &FigureDialog::exportFinished, this, [=](const QString&, bool good, const QString& message) {
    report("figure", good, message);
    reports();
  });
  f->exportTo(script.exportFigure);  // emits exportFinished, also when it cannot start
}

}  // namespace st::ui

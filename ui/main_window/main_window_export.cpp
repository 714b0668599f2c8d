// MainWindow: the Export menu (figures and reports). The dialogs do the work in workers.
#include <QMenu>

#include "figure_dialog.hpp"
#include "candidate_table.hpp"
#include "fit_panel.hpp"
#include "inspector_panel.hpp"
#include "main_window.hpp"
#include "report_dialog.hpp"
#include "session_controller.hpp"
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
    ctx.selectedCandidates = [this] { return m_candidates->selectedCandidates(); };
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

}  // namespace st::ui

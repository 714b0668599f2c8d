// MainWindow: the Export menu (figures and reports). The dialogs do the work in workers.
#include <QMenu>
#include <set>

#include "figure_dialog.hpp"
#include "inspector_panel.hpp"
#include "main_window.hpp"
#include "processing_panel.hpp"
#include "report_dialog.hpp"
#include "search_panel.hpp"
#include "session_snapshot.hpp"

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
    ctx.makeSession = [this](const nlohmann::json& settings) {
      SessionParameters p;
      p.stages = m_processing->stages();
      p.grid = m_search->grid();
      p.search = m_search->params();
      p.backend = m_search->backendKind();
      p.demo = m_demoGrid;
      // The input files, in frame order, once each (empty for the simulated demo).
      std::vector<std::string> inputs;
      std::set<std::string> seen;
      if (m_obs->raw())
        for (const auto& f : m_obs->raw()->info())
          if (!f.file.empty() && seen.insert(f.file).second) inputs.push_back(f.file);
      return makeSession(*m_obs, inputs, p, settings);
    };
    m_reportDialog = new ReportDialog(std::move(ctx), this);
  }
  return m_reportDialog;
}

}  // namespace st::ui

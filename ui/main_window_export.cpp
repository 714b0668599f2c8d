// MainWindow: the Export menu (figures and reports). The dialogs do the work in workers.
#include <QMenu>

#include "figure_dialog.hpp"
#include "inspector_panel.hpp"
#include "main_window.hpp"

namespace st::ui {

void MainWindow::buildExportMenu(QMenu* menu) {
  menu->addAction("Export &figure…", QKeySequence("Ctrl+E"), this, [this] {
    FigureDialog* d = figureDialog();
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

}  // namespace st::ui

// MainWindow: the candidate inspector and co-moving fit docks, and the fit's action (F; Run menu and the
// candidates table's context menu).
#include <QAction>
#include <QDockWidget>
#include <QScrollArea>
#include <QTableView>

#include "candidate_inspector.hpp"
#include "candidate_table.hpp"
#include "fit_panel.hpp"
#include "main_window.hpp"

namespace st::ui {

void MainWindow::buildVettingDocks(QDockWidget* besideInspector, QDockWidget* candidates) {
  m_candidateInspector = new CandidateInspector(m_obs, &m_services, this);
  m_fitPanel = new FitPanel(m_obs, &m_services, this);
  auto* cand = new QDockWidget("Candidate", this);
  cand->setObjectName("dock.candidate");
  auto* scroll = new QScrollArea(cand);  // the inspector scrolls when the dock is short
  scroll->setWidgetResizable(true);
  scroll->setHorizontalScrollBarPolicy(Qt::ScrollBarAlwaysOff);
  scroll->setFrameShape(QFrame::NoFrame);
  scroll->setWidget(m_candidateInspector);
  cand->setWidget(scroll);
  addDockWidget(Qt::RightDockWidgetArea, cand);
  tabifyDockWidget(besideInspector, cand);
  auto* fit = new QDockWidget("Co-moving fit", this);
  fit->setObjectName("dock.fit");
  auto* fitScroll = new QScrollArea(fit);  // the fit's table and plots scroll when the dock is small
  fitScroll->setWidgetResizable(true);
  fitScroll->setFrameShape(QFrame::NoFrame);
  fitScroll->setWidget(m_fitPanel);
  fit->setWidget(fitScroll);
  addDockWidget(Qt::BottomDockWidgetArea, fit);
  splitDockWidget(candidates, fit, Qt::Horizontal);
  resizeDocks({candidates}, {260}, Qt::Vertical);
  resizeDocks({candidates, fit}, {560, 940}, Qt::Horizontal);
  cand->raise();

  // The fit is launched from the candidates table's context menu or with F anywhere in the window (the
  // action lives on the table; buildMenus adds it to the Run menu, which makes the shortcut window-wide).
  auto* fitAction = new QAction("Fit selected candidate (co-moving)", this);
  fitAction->setObjectName("action.fitCandidate");
  fitAction->setShortcut(QKeySequence("F"));
  connect(fitAction, &QAction::triggered, this, [this, fit] {
    fit->show();
    fit->raise();
    m_fitPanel->fitSelected();
  });
  QTableView* table = m_candidates->table();
  table->addAction(fitAction);  // the candidates panel's context menu lists the table's actions
}

}  // namespace st::ui

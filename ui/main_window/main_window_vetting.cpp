// MainWindow: the candidate inspector and co-moving fit docks, and the fit's action (F; Run menu and the
// candidates table's context menu).
#include <QAction>
#include <QDockWidget>
#include <QScrollArea>
#include <QStatusBar>
#include <QTableView>

#include "candidate_inspector.hpp"
#include "candidate_table.hpp"
#include "fit_panel.hpp"
#include "main_window.hpp"
#include "session_controller.hpp"
#include "st/candidate/movers.hpp"

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

  // Pre-processing's movers (sources of the sky-rate stack that moved) offered for vetting.
  auto* movers = new QAction("Add pre-processing's movers as candidates", this);
  movers->setObjectName("action.addMovers");
  movers->setToolTip("Sources that moved between the first and last thirds of the frames (pre-processing "
                     "left them unmasked): listed as candidates with the flag 'pre-processing mover'");
  connect(movers, &QAction::triggered, this, [this] {
    const int added = addMoversAsCandidates();
    statusBar()->showMessage(added > 0 ? QString("Added %1 pre-processing mover%2 as candidates (flag "
                                                 "'pre-processing mover')")
                                             .arg(added)
                                             .arg(added == 1 ? "" : "s")
                                       : QString("No pre-processing mover to add (none, or the search "
                                                 "found them all)"),
                             10000);
  });
  const auto update = [this, movers] {
    const int n = static_cast<int>(pendingMovers().size());
    movers->setEnabled(n > 0);
    movers->setText(n > 0 ? QString("Add pre-processing's %1 mover%2 as candidates").arg(n).arg(n == 1 ? "" : "s")
                          : QString("Add pre-processing's movers as candidates"));
  };
  connect(m_obs, &Observation::resultChanged, this, update);
  connect(m_obs, &Observation::preparedChanged, this, update);
  update();
  table->addAction(movers);
}

std::vector<std::pair<search::Candidate, std::string>> MainWindow::pendingMovers() const {
  std::vector<std::pair<search::Candidate, std::string>> out;
  const auto& prepared = m_obs->prepared();
  const auto& result = m_obs->result();
  if (!result || !prepared || !prepared->products || !m_obs->raw()) return out;
  const auto& movers = prepared->products->movers;
  const int frames = static_cast<int>(m_obs->raw()->frameCount());
  // One mover at a time, to keep each one's note with it (the core function keeps the movers' order).
  for (const detect::MovingSource& m : movers) {
    const auto one = candidate::moverCandidates({m}, result->candidates, frames);
    if (!one.empty()) out.emplace_back(one.front(), candidate::moverNote(m));
  }
  return out;
}

int MainWindow::addMoversAsCandidates() {
  const auto pending = pendingMovers();
  if (pending.empty()) return 0;
  auto result = std::make_shared<search::SearchResult>(*m_obs->result());
  std::vector<session::CandidateState> states = m_obs->candidateStates();
  for (const auto& [c, note] : pending) {
    result->candidates.push_back(c);
    session::CandidateState state;
    state.note = note;
    states.push_back(std::move(state));
  }
  const auto selected = m_obs->selected();
  m_session->continueWith(result.get());  // the same analysis, more candidates: no new session file
  m_obs->setResult(result, std::move(states));
  if (selected) m_obs->setSelected(selected);
  return static_cast<int>(pending.size());
}

}  // namespace st::ui

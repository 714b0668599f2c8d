// CandidatePanel: the vetting keys (candidate_vetting.hpp) and the note editor. Labels go to the Observation
// (Observation::setCandidateLabel), which the session autosaver listens to.
#include <QEvent>
#include <QKeyEvent>
#include <QMenu>
#include <QTableView>

#include "candidate_table.hpp"
#include "candidate_vetting.hpp"

namespace st::ui {

int CandidatePanel::nextUnvettedRow(int proxyRow) const {
  const int rows = m_filter->rowCount();
  for (int k = 1; k <= rows; ++k) {
    const int row = ((proxyRow < 0 ? -1 : proxyRow) + k) % rows;
    if (row == proxyRow) continue;
    const int source = m_filter->mapToSource(m_filter->index(row, 0)).row();
    const auto* state = m_obs->candidateState(source);
    if (state && state->label == session::Label::Unvetted) return row;
  }
  return -1;
}

bool CandidatePanel::labelSelected(session::Label label, session::ArtifactReason reason) {
  const auto selected = m_obs->selected();
  if (!selected || !m_obs->candidateState(*selected)) return false;
  const int source = *selected;
  const QModelIndex proxy = m_filter->mapFromSource(m_model->index(source, 0));
  // The next one is chosen before labelling: the label may take this row out of a filtered view.
  const int nextRow = proxy.isValid() ? nextUnvettedRow(proxy.row()) : -1;
  const int next = nextRow >= 0 ? m_filter->mapToSource(m_filter->index(nextRow, 0)).row() : -1;
  m_syncing = true;  // a row leaving the view must not move the selection on its own
  m_obs->setCandidateLabel(source, label, reason);
  m_syncing = false;
  if (next >= 0)
    m_obs->setSelected(next);
  else
    onSelectionFromObservation();  // stay on it (or clear the table's selection when it left the view)
  return true;
}

bool CandidatePanel::editSelectedNote() {
  const auto selected = m_obs->selected();
  if (!selected || !m_obs->candidateState(*selected)) return false;
  const QModelIndex proxy = m_filter->mapFromSource(m_model->index(*selected, CandidateModel::Note));
  if (!proxy.isValid()) return false;
  m_table->scrollTo(proxy);
  m_table->edit(proxy);
  return true;
}

void CandidatePanel::showVettingMenu(const QPoint& pos) {
  const QModelIndex proxy = m_table->indexAt(pos);
  if (!proxy.isValid()) return;
  m_obs->setSelected(m_filter->mapToSource(proxy).row());
  QMenu menu(this);
  const auto add = [&](QMenu* into, const QString& text, int key) {
    const auto v = vettingKeyFor(key);
    into->addAction(text + "\t" + QKeySequence(key).toString(), this,
                    [this, v] { labelSelected(v->label, v->reason); });
  };
  add(&menu, "Real", Qt::Key_R);
  add(&menu, "Unsure", Qt::Key_U);
  QMenu* artifact = menu.addMenu("Artifact");
  add(artifact, "Charge leakage", Qt::Key_C);
  add(artifact, "Diffraction", Qt::Key_D);
  add(artifact, "Cosmic ray", Qt::Key_X);
  add(artifact, "Ghost", Qt::Key_G);
  add(artifact, "Other", Qt::Key_O);
  add(&menu, "Clear label", Qt::Key_0);
  menu.addSeparator();
  menu.addAction("Edit note…\tN", this, [this] { editSelectedNote(); });
  if (!m_table->actions().isEmpty()) {  // what others put on the table (e.g. the co-moving fit, F)
    menu.addSeparator();
    menu.addActions(m_table->actions());
  }
  menu.exec(m_table->viewport()->mapToGlobal(pos));
}

bool CandidatePanel::eventFilter(QObject* watched, QEvent* event) {
  if (watched != m_table || (event->type() != QEvent::KeyPress && event->type() != QEvent::ShortcutOverride))
    return QWidget::eventFilter(watched, event);
  auto* key = static_cast<QKeyEvent*>(event);
  const auto modifiers = key->modifiers() & ~Qt::KeypadModifier;
  if (modifiers != Qt::NoModifier)  // while the note editor is open, keys go to it, not here
    return QWidget::eventFilter(watched, event);
  const auto vetting = vettingKeyFor(key->key());
  if (!vetting && key->key() != kNoteKey) return QWidget::eventFilter(watched, event);
  if (event->type() == QEvent::ShortcutOverride) {
    // Our key, not a window shortcut's (e.g. the View menu's C): ask for the key press instead.
    event->accept();
    return true;
  }
  if (vetting)
    labelSelected(vetting->label, vetting->reason);
  else
    editSelectedNote();
  return true;
}

}  // namespace st::ui

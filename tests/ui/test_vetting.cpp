// Vetting in the candidates table by keyboard (issue 8 §2): each key labels the selected candidate with the
// right label and reason and moves to the next unvetted one in the table's order; the filter by label; the
// note editor; row colours; keys with modifiers are left alone.
#include <gtest/gtest.h>

#include <QComboBox>
#include <QLineEdit>
#include <QTableView>
#include <QTest>

#include "candidate_table.hpp"
#include "candidate_vetting.hpp"
#include "ui_test_support.hpp"

using namespace st;
using namespace st::ui;
using session::ArtifactReason;
using session::Label;

namespace {

/// Five candidates with SNR 20, 15, 12, 9, 8 (already in decreasing order: table row = result index).
void fiveCandidates(Observation& obs) {
  obs.setRaw(std::make_shared<const FrameCube>(test::movingDotCube(100, 100, 10, {}, 50, 50)), "t");
  auto result = std::make_shared<search::SearchResult>();
  for (const double snr : {20.0, 15.0, 12.0, 9.0, 8.0}) {
    search::Candidate c;
    c.x = 50;
    c.y = 50;
    c.snr = snr;
    c.nIn = 10;
    result->candidates.push_back(c);
  }
  obs.setResult(result);
}

Label labelOf(const Observation& obs, int i) {
  return obs.candidateState(i)->label;
}
ArtifactReason reasonOf(const Observation& obs, int i) {
  return obs.candidateState(i)->reason;
}

}  // namespace

TEST(Vetting, KeysLabelAndAdvanceToTheNextUnvetted) {
  Observation obs;
  fiveCandidates(obs);
  CandidatePanel panel(&obs);
  QTableView* table = panel.table();
  obs.setSelected(0);
  QTest::keyClick(table, Qt::Key_R);
  EXPECT_EQ(labelOf(obs, 0), Label::Real);
  EXPECT_EQ(reasonOf(obs, 0), ArtifactReason::None);
  EXPECT_EQ(obs.selected(), 1);
  QTest::keyClick(table, Qt::Key_D);
  EXPECT_EQ(labelOf(obs, 1), Label::Artifact);
  EXPECT_EQ(reasonOf(obs, 1), ArtifactReason::Diffraction);
  EXPECT_EQ(obs.selected(), 2);
  QTest::keyClick(table, Qt::Key_U);
  EXPECT_EQ(labelOf(obs, 2), Label::Unsure);
  EXPECT_EQ(obs.selected(), 3);
  // The table follows the observation's selection.
  EXPECT_EQ(table->currentIndex().row(), 3);
  // 0 leaves 3 unvetted and moves on; X on the last one wraps round to the first unvetted (3).
  QTest::keyClick(table, Qt::Key_0);
  EXPECT_EQ(labelOf(obs, 3), Label::Unvetted);
  EXPECT_EQ(obs.selected(), 4);
  QTest::keyClick(table, Qt::Key_X);
  EXPECT_EQ(labelOf(obs, 4), Label::Artifact);
  EXPECT_EQ(reasonOf(obs, 4), ArtifactReason::CosmicRay);
  EXPECT_EQ(obs.selected(), 3);
  // Relabelling keeps one reason only; Backspace clears label and reason.
  obs.setSelected(1);
  QTest::keyClick(table, Qt::Key_C);
  EXPECT_EQ(reasonOf(obs, 1), ArtifactReason::ChargeLeakage);
  obs.setSelected(1);
  QTest::keyClick(table, Qt::Key_Backspace);
  EXPECT_EQ(labelOf(obs, 1), Label::Unvetted);
  EXPECT_EQ(reasonOf(obs, 1), ArtifactReason::None);
  obs.setSelected(1);
  QTest::keyClick(table, Qt::Key_G);
  EXPECT_EQ(reasonOf(obs, 1), ArtifactReason::Ghost);
  obs.setSelected(3);
  QTest::keyClick(table, Qt::Key_O);
  EXPECT_EQ(reasonOf(obs, 3), ArtifactReason::Other);
  // Every candidate vetted: the selection stays.
  EXPECT_EQ(obs.selected(), 3);
  // A key with a modifier (Ctrl+R is Run > Search) is not a label.
  obs.setSelected(0);
  QTest::keyClick(table, Qt::Key_U, Qt::ControlModifier);
  EXPECT_EQ(labelOf(obs, 0), Label::Real);
}

TEST(Vetting, AdvanceFollowsTheSortedOrderAndFilterByLabel) {
  Observation obs;
  fiveCandidates(obs);
  CandidatePanel panel(&obs);
  QTableView* table = panel.table();
  table->sortByColumn(CandidateModel::Snr, Qt::AscendingOrder);  // rows: 4, 3, 2, 1, 0
  obs.setSelected(4);
  QTest::keyClick(table, Qt::Key_R);
  EXPECT_EQ(obs.selected(), 3);
  QTest::keyClick(table, Qt::Key_D);
  QTest::keyClick(table, Qt::Key_U);
  EXPECT_EQ(obs.selected(), 1);
  auto* combo = panel.findChild<QComboBox*>();
  ASSERT_NE(combo, nullptr);
  const auto rows = [&](const char* label) {
    combo->setCurrentText(label);
    return table->model()->rowCount();
  };
  EXPECT_EQ(rows("Unvetted"), 2);
  EXPECT_EQ(rows("Real"), 1);
  EXPECT_EQ(rows("Artifact"), 1);
  EXPECT_EQ(rows("Unsure"), 1);
  EXPECT_EQ(rows("All"), 5);
  // Labelling inside the "Unvetted" view: the row leaves the view and the next unvetted one is selected.
  combo->setCurrentText("Unvetted");
  obs.setSelected(1);
  QTest::keyClick(table, Qt::Key_R);
  EXPECT_EQ(table->model()->rowCount(), 1);
  EXPECT_EQ(obs.selected(), 0);
  QTest::keyClick(table, Qt::Key_R);
  EXPECT_EQ(table->model()->rowCount(), 0);
  EXPECT_EQ(obs.selected(), 0);  // nothing left to vet: the selection stays on the last one labelled
}

TEST(Vetting, NoteEditorColumnsAndColours) {
  Observation obs;
  fiveCandidates(obs);
  CandidatePanel panel(&obs);
  panel.resize(900, 300);
  panel.show();
  QTableView* table = panel.table();
  table->setFocus();
  obs.setSelected(2);
  QTest::keyClick(table, Qt::Key_N);
  auto* editor = table->findChild<QLineEdit*>();
  ASSERT_NE(editor, nullptr) << "N did not open the note editor";
  editor->selectAll();
  QTest::keyClicks(editor, "bleed trail of the star at x 51");
  QTest::keyClick(editor, Qt::Key_Return);
  QApplication::processEvents();  // the delegate commits through a queued call
  EXPECT_EQ(obs.candidateState(2)->note, "bleed trail of the star at x 51");
  EXPECT_EQ(obs.selected(), 2);  // a note does not advance
  EXPECT_EQ(labelOf(obs, 2), Label::Unvetted);

  QTest::keyClick(table, Qt::Key_C);
  QAbstractItemModel* m = table->model();
  EXPECT_EQ(m->index(2, CandidateModel::Label).data().toString(), "artifact");
  EXPECT_EQ(m->index(2, CandidateModel::Reason).data().toString(), "charge leakage");
  EXPECT_EQ(m->index(2, CandidateModel::Note).data().toString(), "bleed trail of the star at x 51");
  EXPECT_EQ(m->headerData(CandidateModel::Note, Qt::Horizontal).toString(), "note");
  // Row tint: red for an artifact, none for an unvetted row, the label cell stronger.
  const QColor cell = m->index(2, CandidateModel::Label).data(Qt::BackgroundRole).value<QColor>();
  const QColor row = m->index(2, CandidateModel::Snr).data(Qt::BackgroundRole).value<QColor>();
  EXPECT_GT(cell.red(), cell.green());
  EXPECT_GT(cell.alpha(), row.alpha());
  EXPECT_FALSE(m->index(0, CandidateModel::Snr).data(Qt::BackgroundRole).isValid());
  // The label cell's swatch (visible on a selected row, whose background is the selection colour).
  EXPECT_EQ(m->index(2, CandidateModel::Label).data(Qt::DecorationRole).value<QColor>(), cell);
  EXPECT_FALSE(m->index(0, CandidateModel::Label).data(Qt::DecorationRole).isValid());
  EXPECT_TRUE(vettingShortcutHelp().contains("charge leakage"));
  EXPECT_TRUE(m->index(0, CandidateModel::Snr).data(Qt::ToolTipRole).toString().contains("Backspace"));
}

ST_UI_TEST_MAIN()

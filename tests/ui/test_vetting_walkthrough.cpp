// The vetting GUI as astronomers use it (issue 18 §6): markers on the image and the velocity map coloured by
// label (as the DS9 export) and hidden by the table's label filter; Esc pressed to close a drop-down does not
// cancel a running search, a long search asks first, and the previous velocity map stays until a new search
// completes; the play/pause button uses the style's icons (the "⏸" glyph showed as an empty box); the table
// labels the expected false-alarm count as such.
#include <gtest/gtest.h>

#include <QAbstractItemView>
#include <QComboBox>
#include <QMessageBox>
#include <QTableView>
#include <QTest>
#include <QStatusBar>
#include <QToolButton>

#include "candidate_inspector.hpp"
#include "candidate_table.hpp"
#include "image_view.hpp"
#include "job_runner.hpp"
#include "main_window.hpp"
#include "search_panel.hpp"
#include "st/candidate/candidate_measurement.hpp"
#include "ui_test_support.hpp"
#include "velocity_map_widget.hpp"

using namespace st;
using namespace st::ui;
using session::Label;

namespace {

/// A window with the demo pre-processed and searched (fake backend; `slowdownMs` per velocity).
std::unique_ptr<MainWindow> searchedWindow(int slowdownMs = 0) {
  auto w = std::make_unique<MainWindow>(test::fakeServices(test::movingDotCube(96, 64, 12, {6.0, -3.0}, 30, 40),
                                                           slowdownMs));
  w->resize(1200, 760);
  w->show();
  w->openDemo();
  EXPECT_TRUE(test::waitFor([&] { return w->observation()->prepared() && !w->jobs()->busy(); }));
  w->searchPanel()->setGridPxS({6.0, -3.0}, 3.0, 0.5);
  w->runSearch();
  EXPECT_TRUE(test::waitFor([&] { return w->observation()->result() && !w->jobs()->busy(); }));
  return w;
}

QColor colourOf(Label label) {
  return QColor(candidate::labelColour(label));
}

}  // namespace

TEST(VettingWalkthrough, MarkersAreColouredByLabelAndFollowTheLabelFilter) {
  auto w = searchedWindow();
  Observation* obs = w->observation();
  const int n = static_cast<int>(obs->result()->candidates.size());
  ASSERT_GE(n, 3);
  obs->setCandidateLabel(0, Label::Real);
  obs->setCandidateLabel(1, Label::Artifact, session::ArtifactReason::Ghost);
  obs->setSelected(2);
  QCoreApplication::processEvents();
  const auto& markers = w->imageView()->markers();
  ASSERT_EQ(static_cast<int>(markers.size()), std::min(n, 100));
  EXPECT_EQ(markers[0].colour, colourOf(Label::Real));
  EXPECT_EQ(markers[1].colour, colourOf(Label::Artifact));
  EXPECT_EQ(markers[2].colour, colourOf(Label::Unvetted));
  EXPECT_GT(markers[2].width, markers[0].width);  // the selected candidate is drawn thicker
  VelocityMapWidget* map = w->velocityMap();
  EXPECT_EQ(map->candidatePoints(Label::Real), 1);
  EXPECT_EQ(map->candidatePoints(Label::Artifact), 1);
  EXPECT_EQ(map->candidatePoints(Label::Unvetted), n - 2);

  // "Real" in the label filter: the artifact and the unvetted ones leave the image and the velocity map (the
  // table moves the selection to a row it still shows: candidate 1).
  auto* filter = w->candidates()->findChild<QComboBox*>();
  ASSERT_TRUE(filter);
  filter->setCurrentText("Real");
  QCoreApplication::processEvents();
  ASSERT_EQ(w->imageView()->markers().size(), 1u);
  EXPECT_EQ(w->imageView()->markers()[0].colour, colourOf(Label::Real));
  EXPECT_EQ(w->imageView()->markers()[0].label, "#1");
  EXPECT_EQ(map->candidatePoints(Label::Real), 1);
  EXPECT_EQ(map->candidatePoints(Label::Artifact), 0);
  EXPECT_EQ(map->candidatePoints(Label::Unvetted), 0);
  // Relabelling under the filter updates both at once.
  obs->setCandidateLabel(1, Label::Real);
  QCoreApplication::processEvents();
  EXPECT_EQ(map->candidatePoints(Label::Real), 2);
  filter->setCurrentText("All");
  QCoreApplication::processEvents();
  EXPECT_EQ(static_cast<int>(w->imageView()->markers().size()), std::min(n, 100));
}

TEST(VettingWalkthrough, EscClosingADropDownDoesNotCancelTheSearchAndTheOldMapStays) {
  auto w = searchedWindow(10);  // the fake backend sleeps 10 ms per velocity
  const auto first = w->observation()->result();
  ASSERT_TRUE(first);
  // A slow search (625 velocities, ~6 s) on a different grid.
  w->searchPanel()->setGridPxS({6.0, -3.0}, 6.0, 0.5);
  w->runSearch();
  ASSERT_TRUE(test::waitFor([&] { return w->jobs()->busy(); }, 5000));
  // A drop-down is open (the table's label filter) and Esc is pressed to close it.
  auto* combo = w->candidates()->findChild<QComboBox*>();
  ASSERT_TRUE(combo);
  w->activateWindow();
  combo->showPopup();
  ASSERT_TRUE(test::waitFor([&] { return QApplication::activePopupWidget() != nullptr; }, 3000));
  QTest::keyClick(QApplication::activePopupWidget(), Qt::Key_Escape);
  QCoreApplication::processEvents();
  EXPECT_EQ(QApplication::activePopupWidget(), nullptr);
  EXPECT_TRUE(w->jobs()->busy()) << "Esc for the drop-down cancelled the search";
  // The same through Run > Cancel's slot itself (what the Esc shortcut calls), with the popup open.
  combo->showPopup();
  ASSERT_TRUE(test::waitFor([&] { return QApplication::activePopupWidget() != nullptr; }, 3000));
  w->cancelFromKey();
  QCoreApplication::processEvents();
  EXPECT_EQ(QApplication::activePopupWidget(), nullptr);
  EXPECT_TRUE(w->jobs()->busy()) << "Run > Cancel with a drop-down open cancelled the search";
  // Meanwhile the previous result and its map are still shown.
  EXPECT_EQ(w->observation()->result(), first);
  EXPECT_EQ(w->velocityMap()->candidatePoints(Label::Unvetted), static_cast<int>(first->candidates.size()));
  // Esc on the window now cancels (the search is younger than kAskBeforeCancelS, so without asking).
  w->cancelFromKey();
  ASSERT_TRUE(test::waitFor([&] { return !w->jobs()->busy(); }, 5000));
  EXPECT_EQ(w->observation()->result(), first);
  EXPECT_TRUE(w->searchPanel()->statusText().contains("cancelled")) << w->searchPanel()->statusText().toStdString();
}

TEST(VettingWalkthrough, PlayButtonUsesIconsAndFalseAlarmsAreCounts) {
  auto w = searchedWindow();
  auto* play = w->candidateInspector()->findChild<QToolButton*>("inspector.play");
  ASSERT_TRUE(play);
  EXPECT_TRUE(play->text().isEmpty());
  EXPECT_FALSE(play->icon().isNull());
  QTableView* table = w->candidates()->table();
  const auto* model = table->model();
  bool found = false;
  for (int c = 0; c < model->columnCount(); ++c) {
    const QString h = model->headerData(c, Qt::Horizontal).toString();
    EXPECT_NE(h, "FAP");
    if (h == "false alarms") {
      found = true;
      EXPECT_TRUE(model->headerData(c, Qt::Horizontal, Qt::ToolTipRole).toString().contains("count"));
    }
  }
  EXPECT_TRUE(found);
}

TEST(VettingWalkthrough, TheWindowFitsA1366x768Screen) {
  auto w = searchedWindow();
  const QSize min = w->minimumSizeHint().expandedTo(w->minimumSize());
  EXPECT_LE(min.width(), 1366) << min.width() << " x " << min.height();
  EXPECT_LE(min.height(), 768 - 40) << min.width() << " x " << min.height();  // a taskbar of 40 px
  w->resize(1366, 728);
  QCoreApplication::processEvents();
  EXPECT_LE(w->height(), 728);
  EXPECT_LE(w->statusBar()->geometry().bottom(), w->height());
}

ST_UI_TEST_MAIN_ISOLATED()

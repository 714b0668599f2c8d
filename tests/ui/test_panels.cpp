// Panels on their own: the candidate table sorts by number and filters by SNR, FAP and flags; the
// processing panel returns the stages as the user set them and resets to the paper's defaults; the search
// panel's grid follows the units.
#include <gtest/gtest-spi.h>
#include <gtest/gtest.h>

#include <QDoubleSpinBox>
#include <QGroupBox>
#include <QMessageBox>
#include <QTableView>

#include "candidate_table.hpp"
#include "processing_panel.hpp"
#include "search_panel.hpp"
#include "ui_test_support.hpp"

using namespace st;
using namespace st::ui;

TEST(CandidatePanel, SortsNumericallyAndFilters) {
  Observation obs;
  obs.setRaw(std::make_shared<const FrameCube>(test::movingDotCube(100, 100, 10, {}, 50, 50)), "t");
  auto result = std::make_shared<search::SearchResult>();
  const double snrs[] = {9.0, 12.0, 100.0, 7.5};
  for (int i = 0; i < 4; ++i) {
    search::Candidate c;
    c.x = i == 3 ? 1 : 50;  // the last one sits on the edge
    c.y = 50;
    c.snr = snrs[i];
    c.fap = std::pow(10.0, -static_cast<double>(i));
    c.nIn = 10;
    result->candidates.push_back(c);
  }
  obs.setResult(result);
  CandidatePanel panel(&obs);
  QAbstractItemModel* m = panel.table()->model();
  ASSERT_EQ(m->rowCount(), 4);
  // Sorted by decreasing SNR as numbers (100 before 12 before 9, which text order would get wrong).
  EXPECT_DOUBLE_EQ(m->index(0, CandidateModel::Snr).data(Qt::UserRole).toDouble(), 100.0);
  EXPECT_DOUBLE_EQ(m->index(1, CandidateModel::Snr).data(Qt::UserRole).toDouble(), 12.0);
  panel.filter()->setMinSnr(10.0);
  EXPECT_EQ(m->rowCount(), 2);
  panel.filter()->setMinSnr(0.0);
  panel.filter()->setMaxFap(0.05);  // faps 1, 0.1, 0.01, 0.001
  EXPECT_EQ(m->rowCount(), 2);
  panel.filter()->setMaxFap(1.0);
  panel.filter()->setFlagText("edge");
  ASSERT_EQ(m->rowCount(), 1);
  EXPECT_DOUBLE_EQ(m->index(0, CandidateModel::Snr).data(Qt::UserRole).toDouble(), 7.5);
  panel.filter()->setFlagText("-");
  EXPECT_EQ(m->rowCount(), 3);
  // Selecting a row selects that candidate (source index) in the observation.
  panel.filter()->setFlagText("");
  panel.table()->selectRow(0);
  ASSERT_TRUE(obs.selected().has_value());
  EXPECT_EQ(*obs.selected(), 2);  // the SNR-100 candidate is the third in the result
}

TEST(ProcessingPanel, ReturnsEditedStagesAndResetsToDefaults) {
  std::vector<StageSpec> stages = {
      {"Cosmic rays", true, true, {StageParam{"cr", "Threshold", "σ", 7.0, 1, 50, 1, ""}}},
      {"Background", true, false, {StageParam{"xi", "ξ", "σ", 4.0, 1, 20, 1, ""}}}};
  ProcessingPanel panel(stages);
  auto spins = panel.findChildren<QDoubleSpinBox*>();
  ASSERT_EQ(spins.size(), 2);
  spins[0]->setValue(9.5);
  panel.findChildren<QGroupBox*>()[0]->setChecked(false);
  auto edited = panel.stages();
  EXPECT_FALSE(edited[0].enabled);
  EXPECT_DOUBLE_EQ(edited[0].params[0].value, 9.5);
  EXPECT_TRUE(edited[1].enabled);
  panel.resetDefaults();
  edited = panel.stages();
  EXPECT_TRUE(edited[0].enabled);
  EXPECT_DOUBLE_EQ(edited[0].params[0].value, 7.0);
}

TEST(SearchPanel, GridInPixelUnitsAndDegPerDayAgree) {
  Observation obs;
  FrameCube cube = test::movingDotCube(64, 64, 31, {}, 10, 10);  // 3 s span
  cube.plateScaleArcsecPerPx = 0.5;
  obs.setRaw(std::make_shared<const FrameCube>(std::move(cube)), "t");
  SearchPanel panel(&obs, {});
  panel.setGridPxS({0.2, -0.1}, 1.0, 0.25);
  const search::VelocityGrid g = panel.grid();
  EXPECT_EQ(g.nvx, 9);  // +-1 px/s in steps of 0.25
  EXPECT_NEAR(g.stepPxS, 0.25, 1e-9);
  EXPECT_NEAR(g.centre.vx, 0.2, 1e-9);
  EXPECT_NEAR(g.centre.vy, -0.1, 1e-9);
  // The panel shows deg/day for a cube with a plate scale; the grid in px/s is unchanged by the unit.
  EXPECT_EQ(obs.unit(), VelocityUnit::DegPerDay);
  EXPECT_EQ(obs.grid().nvx, 9);
}

// The test main's watchdog: a modal dialog that no test answers fails its test with its text and is closed,
// instead of blocking until ctest's timeout.
TEST(UiTestWatchdog, AModalDialogLeftOpenFailsTheTestAndIsClosed) {
  test::modalWatchdogSeconds = 2;
  EXPECT_NONFATAL_FAILURE(QMessageBox::warning(nullptr, "Unexpected", "nobody answers this box"),
                          "nobody answers this box");
  test::modalWatchdogSeconds = 30;
}

ST_UI_TEST_MAIN()

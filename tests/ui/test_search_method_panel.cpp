// The search panel's method selector (issue 9): Auto / Exact / Tree with the trade-off in its tooltip, the
// estimate following the selection (Auto resolves to exact on a small cube and to the tree on a larger one,
// as the core's method choice does), the GPU's name in the backend list, and the summary of the last search
// saying which method ran, why, and on which backend.
#include <gtest/gtest.h>

#include <QComboBox>
#include <QLabel>
#include <QGroupBox>
#include <QTest>
#include <cstdlib>

#include "search_panel.hpp"
#include "ui_test_support.hpp"

using namespace st;
using namespace st::ui;

namespace {

QComboBox* methodCombo(SearchPanel& panel) {
  for (auto* c : panel.findChildren<QComboBox*>())
    if (c->findData("tree") >= 0) return c;
  return nullptr;
}

QComboBox* backendCombo(SearchPanel& panel) {
  for (auto* c : panel.findChildren<QComboBox*>())
    if (c->findText("CPU") >= 0) return c;
  return nullptr;
}

/// The estimate's method line (the one after the trial count), once the worker that builds the tree plan
/// is done.
QString methodLine(const SearchPanel& panel) {
  EXPECT_TRUE(test::waitFor([&] { return !panel.estimating(); }, 10000));
  const QStringList lines = panel.estimateText().split('\n');
  return lines.size() > 1 ? lines[1] : QString();
}

}  // namespace

TEST(SearchMethodPanel, SelectorDefaultsToAutoAndExplainsTheTradeOff) {
  setenv("ST_THREADS", "2", 1);  // the cost model depends on the worker count
  Observation obs;
  obs.setRaw(std::make_shared<const FrameCube>(test::movingDotCube(64, 64, 31, {}, 10, 10)), "t");
  SearchPanel panel(&obs, {});
  QComboBox* method = methodCombo(panel);
  ASSERT_NE(method, nullptr);
  EXPECT_EQ(method->count(), 3);
  EXPECT_EQ(panel.method(), st::search::SearchMethod::Auto);
  EXPECT_EQ(panel.params().method, st::search::SearchMethod::Auto);
  const QString tip = method->toolTip();
  EXPECT_TRUE(tip.contains("N_pix·N_v")) << tip.toStdString();
  EXPECT_TRUE(tip.contains("median ~1%") && tip.contains("worst ~5%")) << tip.toStdString();
  // The grid's tooltip says the demo grid is a demo setting and the default is the paper's.
  const QString gridTip = panel.findChildren<QGroupBox*>().front()->toolTip();
  EXPECT_TRUE(gridTip.contains("±12 deg/day") && gridTip.contains("demo")) << gridTip.toStdString();
  // Small cube: Auto resolves to exact, and says so; the keyboard walks the selector, the estimate follows.
  panel.setGridPxS({}, 1.0, 0.25);
  EXPECT_TRUE(methodLine(panel).startsWith("Auto → exact:")) << panel.estimateText().toStdString();
  QTest::keyClick(method, Qt::Key_Down);
  EXPECT_EQ(panel.params().method, st::search::SearchMethod::Exact);
  EXPECT_TRUE(methodLine(panel).startsWith("exact:")) << panel.estimateText().toStdString();
  EXPECT_TRUE(methodLine(panel).contains("(tree ~")) << panel.estimateText().toStdString();
  QTest::keyClick(method, Qt::Key_Down);
  EXPECT_EQ(panel.params().method, st::search::SearchMethod::Tree);
  EXPECT_TRUE(methodLine(panel).startsWith("tree:")) << panel.estimateText().toStdString();
  EXPECT_TRUE(methodLine(panel).contains("exact ~")) << panel.estimateText().toStdString();
  panel.setMethod("auto");
  EXPECT_EQ(panel.method(), st::search::SearchMethod::Auto);
  panel.setMethod("fastest");  // ignored
  EXPECT_EQ(panel.method(), st::search::SearchMethod::Auto);
}

TEST(SearchMethodPanel, AutoResolvesToTheTreeWhereItPays) {
  setenv("ST_THREADS", "2", 1);
  // 500 frames 0.1 s apart, 256^2 px, 31 x 31 velocities 1 px over the span apart: ~3e10 exact additions,
  // the tree ~100x fewer (the core's choice: tree; bench: exact 2.4 CPU-s, tree 0.4).
  Observation obs;
  obs.setRaw(std::make_shared<const FrameCube>(test::movingDotCube(256, 256, 500, {}, 10, 10)), "t");
  SearchPanel panel(&obs, {});
  const double step = 1.0 / obs.raw()->timeSpanS();
  panel.setGridPxS({}, 15 * step, step);
  ASSERT_EQ(panel.grid().nvx, 31);
  EXPECT_TRUE(methodLine(panel).startsWith("Auto → tree:")) << panel.estimateText().toStdString();
  EXPECT_TRUE(methodLine(panel).contains("the additions")) << panel.estimateText().toStdString();
}

TEST(SearchMethodPanel, BackendListNamesTheGpuAndTheSummarySaysWhatRan) {
  Observation obs;
  obs.setRaw(std::make_shared<const FrameCube>(test::movingDotCube(64, 64, 31, {}, 10, 10)), "t");
  SearchPanel panel(&obs, {"NVIDIA H100 80GB HBM3, 79.1 GiB"});
  QComboBox* backend = backendCombo(panel);
  ASSERT_NE(backend, nullptr);
  EXPECT_EQ(backend->itemText(2), "GPU: NVIDIA H100 80GB HBM3, 79.1 GiB");
  // With a GPU possible the estimate says its figures are the CPU's.
  ASSERT_TRUE(test::waitFor([&] { return !panel.estimating(); }, 10000));
  EXPECT_TRUE(panel.estimateText().contains("CPU figures")) << panel.estimateText().toStdString();
  backend->setCurrentIndex(1);  // CPU
  EXPECT_FALSE(panel.estimateText().contains("CPU figures")) << panel.estimateText().toStdString();

  auto result = std::make_shared<search::SearchResult>();
  result->method = st::search::SearchMethod::Tree;
  result->methodReason = "auto: tree, clearly faster (estimated exact 56 s, tree 4 s; 110x fewer additions)";
  result->backend = "cpu";
  result->snrThreshold = 7.0;
  result->elapsedS = 4.2;
  result->candidates.resize(3);
  obs.setResult(result);
  const QString status = panel.statusText();
  EXPECT_TRUE(status.startsWith("tree search on cpu: 3 candidates")) << status.toStdString();
  EXPECT_TRUE(status.contains("auto: tree, clearly faster")) << status.toStdString();
  result = std::make_shared<search::SearchResult>(*result);
  result->method = st::search::SearchMethod::Exact;
  result->methodReason = "requested";
  result->candidates.resize(1);
  result->sidelobesMerged = 2;
  obs.setResult(result);
  EXPECT_TRUE(
      panel.statusText().startsWith("exact search on cpu: 1 candidate above SNR 7.00 (2 sidelobes merged)"))
      << panel.statusText().toStdString();
  EXPECT_TRUE(panel.statusText().contains("as selected")) << panel.statusText().toStdString();
  EXPECT_FALSE(panel.statusText().contains("noise of the statistic")) << panel.statusText().toStdString();
  // The statistic's measured noise, when the search measured it.
  result = std::make_shared<search::SearchResult>(*result);
  result->statisticNoise.scale = 1.0604;
  result->statisticNoise.mean = 0.0049;
  result->statisticNoise.cells = 19999;
  obs.setResult(result);
  EXPECT_TRUE(panel.statusText().contains(
      "noise of the statistic on this cube: 1.060 x the unit, mean 0.00 (the paper assumes 1 and 0)"))
      << panel.statusText().toStdString();

  // A GPU failure that the CPU made up for is said first; the backend's note is on hover.
  result = std::make_shared<search::SearchResult>(*result);
  result->warnings = {"cuda: NVIDIA H100 failed (out of memory); searched on cpu instead"};
  result->backendNote = "device 0: cube resident (1500 MiB)";
  obs.setResult(result);
  EXPECT_TRUE(panel.statusText().startsWith("Warning: cuda: NVIDIA H100 failed (out of memory)"))
      << panel.statusText().toStdString();
  EXPECT_TRUE(panel.statusText().contains("exact search on cpu")) << panel.statusText().toStdString();
  bool noteShown = false;
  for (const QLabel* label : panel.findChildren<QLabel*>())
    noteShown = noteShown || label->toolTip() == "device 0: cube resident (1500 MiB)";
  EXPECT_TRUE(noteShown);
}

ST_UI_TEST_MAIN()

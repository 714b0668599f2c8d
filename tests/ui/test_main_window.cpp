// The main window driven as a user would, offscreen, on a small synthetic cube with a fake backend: load,
// pre-process, search, select a candidate, scrub velocity space, toggle CSA, cancel, and the event loop
// never stalls while a search runs. Screenshots of the main states go to ./ui_screens/.
#include <gtest/gtest.h>

#include <QDir>
#include <QElapsedTimer>
#include <QTableView>
#include <QTest>
#include <QTimer>

#include <qcustomplot.h>
#include "candidate_table.hpp"
#include "image_view.hpp"
#include "job_runner.hpp"
#include "main_window.hpp"
#include "search_panel.hpp"
#include "stack_scrubber.hpp"
#include "ui_test_support.hpp"
#include "velocity_map_widget.hpp"

using namespace st;
using namespace st::ui;

namespace {

constexpr Velocity kDotV{8.0, -4.0};  // px/s; frames 0.1 s apart, 40 frames: 3.9 s span

std::unique_ptr<MainWindow> loadedWindow(int slowdownMs = 0, int size = 96, std::size_t frames = 40) {
  auto w = std::make_unique<MainWindow>(
      test::fakeServices(test::movingDotCube(size, size, frames, kDotV, 40, 50), slowdownMs));
  w->resize(1400, 900);
  w->show();
  w->openDemo();
  EXPECT_TRUE(test::waitFor([&] { return w->observation()->prepared() != nullptr && !w->jobs()->busy(); }));
  return w;
}

void screenshot(MainWindow& w, const QString& name) {
  QDir().mkpath("ui_screens");
  QApplication::processEvents();
  w.grab().save("ui_screens/" + name + ".png");
}

// The grid spans the dot's velocity: step 1 px over the span, +- 12 steps.
void searchAndWait(MainWindow& w) {
  w.searchPanel()->setGridPxS({6.0, -3.0}, 3.0, 0.5);
  w.runSearch();
  ASSERT_TRUE(test::waitFor([&] { return w.observation()->result() != nullptr && !w.jobs()->busy(); }));
}

}  // namespace

TEST(MainWindow, LoadPreprocessSearchAndSelectFindsTheMovingDot) {
  auto w = loadedWindow();
  EXPECT_EQ(w->observation()->raw()->frameCount(), 40u);
  screenshot(*w, "01_loaded");
  searchAndWait(*w);
  const auto& result = w->observation()->result();
  ASSERT_FALSE(result->candidates.empty());
  const auto& best = result->candidates.front();
  EXPECT_NEAR(best.v.vx, kDotV.vx, 0.5 + 1e-9);  // within a grid step
  EXPECT_NEAR(best.v.vy, kDotV.vy, 0.5 + 1e-9);
  // The best candidate is selected after a search: the velocity follows it and the table shows it.
  ASSERT_TRUE(w->observation()->selected().has_value());
  EXPECT_EQ(*w->observation()->selected(), 0);
  EXPECT_EQ(w->observation()->velocity(), best.v);
  EXPECT_EQ(w->candidates()->table()->model()->rowCount(), static_cast<int>(result->candidates.size()));
  // The live stack at the candidate's velocity reaches the central view, with the dot at full sum.
  ASSERT_TRUE(test::waitFor([&] {
    const auto& img = w->imageView()->image();
    return img && img->width == 96 && img->at(best.x, best.y) > 30.0f;
  }));
  screenshot(*w, "02_searched");
}

TEST(MainWindow, VelocityMapClickAndArrowKeysSetTheVelocity) {
  auto w = loadedWindow();
  searchAndWait(*w);
  VelocityMapWidget* map = w->velocityMap();
  const search::VelocityGrid grid = w->observation()->grid();
  const Velocity target = grid.at(2, 9);
  QApplication::processEvents();
  map->plot()->replot();
  const QPointF p = map->plotPixelOf(target);
  QTest::mouseClick(map->plot(), Qt::LeftButton, Qt::NoModifier, p.toPoint());
  EXPECT_NEAR(w->observation()->velocity().vx, target.vx, 1e-9);
  EXPECT_NEAR(w->observation()->velocity().vy, target.vy, 1e-9);
  QTest::keyClick(map, Qt::Key_Right);
  EXPECT_NEAR(w->observation()->velocity().vx, target.vx + grid.stepPxS, 1e-9);
  QTest::keyClick(map, Qt::Key_Up);
  EXPECT_NEAR(w->observation()->velocity().vy, target.vy + grid.stepPxS, 1e-9);
  // The central stack follows the scrubbed velocity.
  const double before = w->lastStackLatencyMs();
  (void)before;
  ASSERT_TRUE(test::waitFor([&] { return w->scrubber()->computedCount() > 0; }));
}

TEST(MainWindow, SelectingACandidateSetsVelocityAndCsaToggles) {
  auto w = loadedWindow();
  searchAndWait(*w);
  const auto& cands = w->observation()->result()->candidates;
  ASSERT_GE(cands.size(), 1u);
  const int last = static_cast<int>(cands.size()) - 1;
  w->selectCandidate(last);
  EXPECT_EQ(w->observation()->velocity(), cands[static_cast<std::size_t>(last)].v);
  // The view is centred on the candidate.
  const QPointF centre =
      w->imageView()->widgetToImage(QPointF(w->imageView()->width() / 2.0, w->imageView()->height() / 2.0));
  EXPECT_NEAR(centre.x(), cands[static_cast<std::size_t>(last)].x, 1.0);
  EXPECT_NEAR(centre.y(), cands[static_cast<std::size_t>(last)].y, 1.0);
  // Selecting through the table does the same.
  w->selectCandidate(0);
  EXPECT_EQ(w->observation()->velocity(), cands.front().v);
  QTest::keyClick(w.get(), Qt::Key_C);
  EXPECT_EQ(w->observation()->stackMode(), search::StackMode::Csa);
  screenshot(*w, "03_csa");
}

TEST(MainWindow, CancelStopsASearchPromptly) {
  auto w = loadedWindow(/*slowdownMs=*/50);
  w->searchPanel()->setGridPxS({0, 0}, 10.0, 0.5);  // 41 x 41 velocities x 50 ms: far longer than the test
  bool cancelled = false;
  QObject::connect(w->jobs(), &JobRunner::finished,
                   [&](JobKind, bool, bool c, const QString&, double) { cancelled = c; });
  w->runSearch();
  ASSERT_TRUE(w->jobs()->busy());
  QTest::qWait(300);
  QElapsedTimer t;
  t.start();
  w->jobs()->cancel();
  ASSERT_TRUE(test::waitFor([&] { return !w->jobs()->busy(); }, 5000));
  EXPECT_LT(t.elapsed(), 500);
  EXPECT_TRUE(cancelled);
  EXPECT_EQ(w->observation()->result(), nullptr);
}

TEST(MainWindow, EventLoopNeverStallsDuringASearch) {
  // A real workload on the worker (stacks of 128^2 x 60 frames for 21^2 velocities) while the GUI thread
  // ticks a 5 ms timer, repaints progress and scrubs: the largest gap between ticks stays under 50 ms.
  auto w = loadedWindow(0, 128, 60);
  w->searchPanel()->setGridPxS({0, 0}, 5.0, 0.5);
  w->searchPanel()->setMethod("exact");  // the workload: auto would take the tree, over in a few ticks
  QElapsedTimer clock;
  qint64 last = 0;
  qint64 maxGap = 0;
  int ticks = 0;
  QTimer timer;
  timer.setInterval(5);
  QObject::connect(&timer, &QTimer::timeout, [&] {
    const qint64 now = clock.elapsed();
    if (ticks++ > 0) maxGap = std::max(maxGap, now - last);
    if (ticks > 1 && now - last > 20)
      std::fprintf(stderr, "gap %lld ms at %lld ms\n", static_cast<long long>(now - last),
                   static_cast<long long>(now));
    last = now;
    if (ticks % 10 == 0) w->observation()->setVelocity({ticks * 0.01, 0.0});  // scrub while searching
  });
  w->runSearch();
  clock.start();
  timer.start();
  ASSERT_TRUE(test::waitFor([&] { return !w->jobs()->busy(); }, 60000));
  timer.stop();
  ASSERT_NE(w->observation()->result(), nullptr);
  EXPECT_GT(ticks, 20);
  EXPECT_LT(maxGap, 50) << "largest event-loop gap " << maxGap << " ms over " << ticks << " ticks";
}

TEST(StackScrubber, LatestRequestWinsAndResultsCarryTheirVelocity) {
  StackScrubber scrubber;
  scrubber.setBackend(std::make_shared<test::FakeBackend>());
  auto cube = std::make_shared<search::FilteredCube>();
  cube->frames = test::movingDotCube(64, 64, 30, kDotV, 30, 30);
  std::vector<Velocity> got;
  QObject::connect(&scrubber, &StackScrubber::stackReady,
                   [&](const std::shared_ptr<const Image>&, const StackRequest& r, double, double) {
                     got.push_back(r.velocity);
                   });
  for (int i = 0; i < 50; ++i)
    scrubber.request(cube, {i * 0.1, 0.0}, search::StackMode::Ipsa);
  ASSERT_TRUE(test::waitFor([&] { return !got.empty() && got.back().vx == 4.9; }));
  EXPECT_LT(got.size(), 50u);  // intermediate requests were dropped, not queued
  EXPECT_GT(scrubber.droppedCount(), 0);
}

ST_UI_TEST_MAIN()

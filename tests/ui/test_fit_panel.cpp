// The co-moving fit panel: a real st::fit::fitComoving on a small noisy synthetic cube (a Moffat source
// moving at a known velocity, started off by 0.2 px/s) through a CoreServices::fitCandidate stand-in. The
// panel plots the cost per iteration (at least two points, decreasing), shows data | model | residual,
// fills the parameter table with the fit's values and sigmas and the false-alarm probability, and "Accept"
// stores the fit on the candidate. A slow fake fit shows live cost points while running and answers
// Cancel within a second.
#include <gtest/gtest.h>

#include <QElapsedTimer>
#include <QLabel>
#include <QPushButton>
#include <QTableView>
#include <QAction>
#include <QTableWidget>
#include <QTest>
#include <qcustomplot.h>
#include <random>
#include <thread>

#include "fit_panel.hpp"
#include "candidate_table.hpp"
#include "st/candidate/candidate_measurement.hpp"
#include "job_runner.hpp"
#include "main_window.hpp"
#include "st/fit/pixel_psf.hpp"
#include "stamp_strip.hpp"
#include "ui_test_support.hpp"

using namespace st;
using namespace st::ui;

namespace {

const psf::Moffat kPsf{2.0, 4.0};
constexpr Velocity kTrueV{1.0, 0.5};

/// 30 frames 1 s apart, 48 x 48, a source of peak 40 moving at kTrueV through (24, 24) at t_ref, Gaussian
/// noise sigma 1 (fixed seed).
FrameCube sourceCube() {
  FrameCube cube(48, 48, 30);
  for (std::size_t n = 0; n < cube.frameCount(); ++n)
    cube.info()[n].mjdMid = 60000.0 + static_cast<double>(n) / 86400.0;
  const auto t = cube.timeOffsetsS();
  std::mt19937 rng(7);
  std::normal_distribution<float> noise(0.0f, 1.0f);
  for (std::size_t n = 0; n < cube.frameCount(); ++n) {
    const double sx = 24.0 + kTrueV.vx * t[n];
    const double sy = 24.0 + kTrueV.vy * t[n];
    for (int y = 0; y < cube.height(); ++y)
      for (int x = 0; x < cube.width(); ++x)
        cube.frame(n)[static_cast<std::size_t>(y) * cube.width() + x] =
            static_cast<float>(40.0 * fit::pixelPsfValue(kPsf, x - sx, y - sy)) + noise(rng);
  }
  return cube;
}

/// An observation with one candidate at (24, 24), velocity (1.2, 0.3) px/s, selected, and trial counts.
void setUp(Observation& obs) {
  obs.setRaw(std::make_shared<const FrameCube>(FrameCube(48, 48, 30)), "synthetic");
  obs.setPrepared(std::make_shared<PreparedView>());
  auto result = std::make_shared<search::SearchResult>();
  search::Candidate c;
  c.x = 24;
  c.y = 24;
  c.v = {1.2, 0.3};
  result->candidates.push_back(c);
  result->trials = {48, 48, 21, 21};
  obs.setResult(result);
  obs.setSelected(0);
}

QString cell(QTableWidget* table, const QString& name, int column) {
  for (int r = 0; r < table->rowCount(); ++r)
    if (table->item(r, 0)->text().startsWith(name)) return table->item(r, column)->text();
  return {};
}

}  // namespace

TEST(FitPanel, RealFitPlotsDecreasingCostFillsTableAndAccepts) {
  auto cube = std::make_shared<const FrameCube>(sourceCube());
  CoreServices services;
  services.fitCandidate = [cube](const PreparedView&, const search::Candidate& c, CancelToken& cancel,
                                 const FitStepCallback& onStep) {
    fit::FitOptions opt;
    opt.psf = kPsf;
    opt.sigmaN = 1.0;
    FitOutcome out;
    out.result = fit::fitComoving(
        *cube, fit::startFromCandidate(c), opt,
        [&](const fit::FitIteration& it) {
          onStep({it, std::make_shared<const Image>(fit::stacksAt(*cube, it.params, opt).residual)});
        },
        cancel);
    out.summary = candidate::summarize(out.result);
    // A segment check with one segment position on the sky (fitCandidate's on real frames).
    out.summary.segments =
        candidate::SegmentSummary{false,
                                  {},
                                  {5.0, 5.1, 4.9, 5.2},
                                  {{2, 60000.5, -3.75, 20.5, 24.25, 0.2, 0.21, 5.1, 150.0, -20.0, {}, {}}},
                                  3};
    return out;
  };
  Observation obs;
  setUp(obs);
  FitPanel panel(&obs, &services);
  bool finished = false;
  bool ok = false;
  QObject::connect(&panel, &FitPanel::fitFinished, [&](bool good, bool, const QString&) {
    finished = true;
    ok = good;
  });
  panel.fitSelected();
  ASSERT_TRUE(test::waitFor([&] { return finished; }, 15000));
  ASSERT_TRUE(ok) << panel.statusText().toStdString();
  const fit::FitResult& r = panel.outcome()->result;
  ASSERT_TRUE(r.ok()) << r.message;
  // The fit found the true velocity (to a few sigma) from a start 0.2 px/s off.
  EXPECT_NEAR(r.params.v.vx, kTrueV.vx, 4 * r.sigmaNoiseModel[fit::kVx] + 1e-3);
  EXPECT_NEAR(r.params.v.vy, kTrueV.vy, 4 * r.sigmaNoiseModel[fit::kVy] + 1e-3);

  // The cost plot: at least two points, the change from the first cost in per cent (0 at the start, the
  // last below it, equal to the history's own change).
  auto* graph = panel.costPlot()->graph(0);
  ASSERT_GE(panel.costPoints(), 2);
  EXPECT_EQ(graph->data()->at(0)->value, 0.0);
  EXPECT_LT(graph->data()->at(graph->dataCount() - 1)->value, 0.0);
  EXPECT_NEAR(graph->data()->at(graph->dataCount() - 1)->value,
              100.0 * (r.costHistory.back() / r.costHistory.front() - 1.0), 1e-9);
  // The live residual at the final parameters is the core's residual stack (same grid and rounding).
  fit::FitOptions liveOptions;
  liveOptions.psf = kPsf;
  const Image live = fit::stacksAt(*cube, r.params, liveOptions).residual;
  ASSERT_EQ(live.width, r.residualStack.width);
  ASSERT_EQ(live.height, r.residualStack.height);
  for (std::size_t k = 0; k < live.size(); ++k)
    ASSERT_NEAR(live.pixels[k], r.residualStack.pixels[k], 1e-3) << k;
  ASSERT_EQ(panel.residualView()->tileCount(), 3);  // data | model | residual
  EXPECT_EQ(panel.residualView()->tile(2).image->width, r.residualStack.width);

  // The table shows the fit's numbers: value, noise-model sigma, Hessian sigma, and the FAP row.
  QTableWidget* table = panel.parameterTable();
  EXPECT_NEAR(cell(table, "vx", 1).toDouble(), r.params.v.vx, 1e-5);
  EXPECT_NEAR(cell(table, "vx", 2).toDouble(), r.sigmaNoiseModel[fit::kVx],
              1e-3 * r.sigmaNoiseModel[fit::kVx]);
  EXPECT_NEAR(cell(table, "vx", 3).toDouble(), r.sigma[fit::kVx], 1e-3 * r.sigma[fit::kVx]);
  EXPECT_NEAR(cell(table, "SNR", 1).toDouble(), r.snr, 1e-3 * r.snr);
  EXPECT_FALSE(cell(table, "FAP", 1).isEmpty());
  // The segment check and each segment's position, the tracklet a report submits.
  EXPECT_EQ(cell(table, "segments (K = 4)", 1), "consistent");
  EXPECT_EQ(cell(table, "segments (K = 4)", 4), "tracklet: 1 position of 3 segments");
  EXPECT_EQ(cell(table, "segment 2/3 (x, y) [px] at t_ref -3.8 s", 1), "20.500, 24.250");
  EXPECT_EQ(cell(table, "segment 2/3 (x, y)", 2), "0.2, 0.21");
  EXPECT_EQ(cell(table, "segment 2/3 (x, y)", 4), "SNR 5.1, RA 150.000000 Dec -20.000000 deg");

  // Accept stores the fit's JSON on the candidate.
  ASSERT_TRUE(panel.acceptButton()->isEnabled());
  EXPECT_FALSE(obs.candidateState(0)->fit.has_value());
  panel.acceptButton()->click();
  ASSERT_TRUE(obs.candidateState(0)->fit.has_value());
  EXPECT_EQ(*obs.candidateState(0)->fit, panel.outcome()->summary);
  EXPECT_TRUE(obs.candidateState(0)->fit->converged());
}

TEST(FitPanel, ShowsLivePointsAndCancelsWithinASecond) {
  CoreServices services;
  services.fitCandidate = [](const PreparedView&, const search::Candidate&, CancelToken& cancel,
                             const FitStepCallback& onStep) -> FitOutcome {
    // An endless, slow "fit": one step every 20 ms, polling cancel in 1 ms slices.
    for (int it = 0;; ++it) {
      fit::FitIteration step;
      step.iteration = it;
      step.cost = 1000.0 / (1.0 + it);
      onStep({step, std::make_shared<const Image>(9, 9, static_cast<float>(it))});
      for (int ms = 0; ms < 20; ++ms) {
        cancel.throwIfCancelled();
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
      }
    }
  };
  Observation obs;
  setUp(obs);
  FitPanel panel(&obs, &services);
  bool finished = false;
  bool cancelled = false;
  QObject::connect(&panel, &FitPanel::fitFinished, [&](bool, bool c, const QString&) {
    finished = true;
    cancelled = c;
  });
  panel.fitSelected();
  ASSERT_TRUE(panel.running());
  // Live: cost points and the residual arrive while the fit runs.
  ASSERT_TRUE(
      test::waitFor([&] { return panel.costPoints() >= 3 && panel.residualView()->tileCount() == 1; }, 5000));
  EXPECT_TRUE(panel.running());
  QElapsedTimer clock;
  clock.start();
  panel.cancel();
  ASSERT_TRUE(test::waitFor([&] { return finished; }, 5000));
  EXPECT_LT(clock.elapsed(), 1000);
  EXPECT_TRUE(cancelled);
  EXPECT_FALSE(panel.acceptButton()->isEnabled());
  EXPECT_EQ(panel.outcome(), nullptr);
}

TEST(FitPanel, LaunchedFromTheMainWindowWithF) {
  CoreServices services = test::fakeServices(test::movingDotCube(64, 64, 20, {4.0, 0.0}, 30, 30));
  int fits = 0;
  services.fitCandidate = [&fits](const PreparedView&, const search::Candidate& c, CancelToken&,
                                  const FitStepCallback& onStep) {
    ++fits;  // on the worker; read after the fit finished
    FitOutcome out;
    for (int it = 0; it < 3; ++it) {
      fit::FitIteration step;
      step.iteration = it;
      step.cost = 10.0 - it;
      onStep({step, nullptr});
    }
    out.result.costHistory = {10.0, 9.0, 8.0};
    out.summary.x = c.x;
    return out;
  };
  MainWindow w(services);
  w.resize(1200, 800);
  w.show();
  w.openDemo();
  ASSERT_TRUE(test::waitFor([&] { return w.observation()->prepared() != nullptr && !w.jobs()->busy(); }));
  auto result = std::make_shared<search::SearchResult>();
  search::Candidate c;
  c.x = 30;
  c.y = 30;
  c.v = {4.0, 0.0};
  result->candidates.push_back(c);
  w.observation()->setResult(result);
  w.selectCandidate(0);

  // The fit action (shortcut F) is on the candidates table, whose (vetting) context menu lists it.
  auto* action = w.findChild<QAction*>("action.fitCandidate");
  ASSERT_TRUE(action);
  EXPECT_EQ(action->shortcut(), QKeySequence("F"));
  EXPECT_TRUE(w.candidates()->table()->actions().contains(action));
  bool finished = false;
  QObject::connect(w.fitPanel(), &FitPanel::fitFinished, [&] { finished = true; });
  w.activateWindow();
  QTest::keyClick(&w, Qt::Key_F);
  ASSERT_TRUE(test::waitFor([&] { return finished; }, 5000));
  EXPECT_EQ(fits, 1);
  EXPECT_EQ(w.fitPanel()->fittedIndex(), 0);
  EXPECT_EQ(w.fitPanel()->costPoints(), 3);
}

/// The line above Fit (found as the panel's first own label, so the test also runs against older builds).
QString title(FitPanel& panel) {
  return panel.findChildren<QLabel*>(QString(), Qt::FindDirectChildrenOnly).front()->text();
}

TEST(FitPanel, TitleFollowsTheState) {
  CoreServices services;
  services.fitCandidate = [](const PreparedView&, const search::Candidate& c, CancelToken&,
                             const FitStepCallback&) {
    FitOutcome out;
    out.result.status = fit::FitStatus::Converged;
    out.result.costHistory = {2.0, 1.0};
    out.summary.x = c.x;
    out.summary.status = fit::FitStatus::Converged;
    return out;
  };
  Observation obs;
  FitPanel panel(&obs, &services);
  EXPECT_TRUE(title(panel).startsWith("No candidates yet")) << title(panel).toStdString();
  setUp(obs);  // one candidate, selected
  EXPECT_TRUE(title(panel).startsWith("Candidate 1 selected")) << title(panel).toStdString();
  EXPECT_TRUE(title(panel).contains("ready to fit")) << title(panel).toStdString();
  EXPECT_FALSE(title(panel).contains("Select a candidate"));
  obs.setSelected(std::nullopt);
  EXPECT_TRUE(title(panel).startsWith("Select one of the 1 candidates")) << title(panel).toStdString();
  obs.setSelected(0);
  bool finished = false;
  QObject::connect(&panel, &FitPanel::fitFinished, [&] { finished = true; });
  panel.fitSelected();
  EXPECT_TRUE(title(panel).contains("fitting")) << title(panel).toStdString();
  ASSERT_TRUE(test::waitFor([&] { return finished; }, 5000));
  EXPECT_TRUE(title(panel).contains("fit done (converged): Accept stores it")) << title(panel).toStdString();
  panel.accept();
  EXPECT_TRUE(title(panel).contains("fit done and stored")) << title(panel).toStdString();
  obs.setResult(std::make_shared<search::SearchResult>());  // a new search without candidates
  EXPECT_TRUE(title(panel).startsWith("The search found no candidate")) << title(panel).toStdString();
}

ST_UI_TEST_MAIN()

// A cube larger than the GUI's memory budget (issue 20 item 4). With Run > Memory limit set small, a
// pre-processed cube opens OUT OF CORE (a banner and the status-bar label say so, with the budget); the view
// shows the mean of all frames read in strips (equal to the in-memory mean); Search runs core's out-of-core
// path (planTiledSearch + searchTiled, as `synthtrack-cli search --preprocessed`) as a job, can be
// cancelled, and finds the same best candidate as the in-memory core search of the same cube; the selected
// candidate's stack is summed in strips and equals stack::stackIpsa. Raw frames whose pre-processing is over
// the budget are pre-processed out of core in the load job's worker (strips of rows) and their filtered cube
// opened out of core. Core: stackOutOfCore equals stack::stackIpsa; planOpen's three answers; the tree
// search in tiles re-scores its candidates as in memory.
//
// ST_OUT_OF_CORE_SCREENSHOT_DIR, when set, gets a grab of the window in the banner state
// (out_of_core_banner.png).
#include <gtest/gtest.h>

#include <QDir>
#include <QFile>
#include <QLabel>
#include <QSettings>
#include <QStatusBar>
#include <algorithm>
#include <chrono>
#include <filesystem>
#include <cstdio>

#include "candidate_inspector.hpp"
#include "fit_panel.hpp"
#include "job_runner.hpp"
#include "main_window.hpp"
#include "observation.hpp"
#include "out_of_core_controller.hpp"
#include "search_panel.hpp"
#include "st/io/fits_reader.hpp"
#include "st/io/fits_writer.hpp"
#include "st/pipeline/out_of_core_cube.hpp"
#include "st/pipeline/prepared_cube.hpp"
#include "st/pipeline/preprocess.hpp"
#include "st/search/cpu_backend.hpp"
#include "st/search/method_choice.hpp"
#include "st/sim/simulator.hpp"
#include "st/stack/ipsa.hpp"
#include "test_support.hpp"
#include "ui_test_support.hpp"

using namespace st;
using namespace st::ui;

namespace {

constexpr int kW = 96, kH = 96;
constexpr std::size_t kFrames = 1024;
const Velocity kV{1.5, -1.0};

/// 1024 filtered frames 0.02 s apart, zero but for a dot of 1 moving at kV through (48, 40) at t_ref: 38 MB
/// on disk.
FrameCube dotCube() {
  FrameCube cube(kW, kH, kFrames);
  for (std::size_t n = 0; n < kFrames; ++n)
    cube.info()[n].mjdMid = 60000.0 + static_cast<double>(n) * 0.02 / 86400.0;
  const auto dt = cube.timeOffsetsS();
  for (std::size_t n = 0; n < kFrames; ++n) {
    const int x = 48 + static_cast<int>(std::lround(kV.vx * dt[n]));
    const int y = 40 + static_cast<int>(std::lround(kV.vy * dt[n]));
    cube.frame(n)[static_cast<std::size_t>(y) * kW + x] = 1.0f;
  }
  return cube;
}

/// `cube` written as a prepared, filtered cube (STPREP, STFILT = T, SIGMAF 0.05, PSFFWHM 2.5).
std::string writePrepared(const test::TempDir& dir, const FrameCube& cube) {
  pipeline::Prepared p;
  p.psf = psf::Moffat::fromFwhm(2.5, pipeline::kDefaultPsfBeta);
  p.psfFitted = true;
  p.sigmaN = 0.05;
  p.filtered.sigmaF = 0.05;
  const std::string path = (dir / "prepared.fits").string();
  io::writeCube(path, cube, pipeline::preparedCubeCards(p, pipeline::PreparedState::Filtered));
  return path;
}

/// The fakes' services with the real planOpen (the out-of-core decision reads the FITS headers).
CoreServices servicesWithPlanOpen() {
  CoreServices s = test::fakeServices(test::movingDotCube(8, 8, 2, {}, 1, 1));
  s.planOpen = [](const std::vector<std::string>& inputs, std::size_t budget, CancelToken& cancel) {
    return pipeline::planOpen(inputs, {}, budget, 2, cancel);
  };
  return s;
}

/// The test's settings removed at its end (each test process has its own settings file: runUiTests).
struct OwnSettings {
  ~OwnSettings() {
    const QString file = QSettings().fileName();
    QSettings().clear();
    QFile::remove(file);
  }
};

}  // namespace

TEST(OutOfCoreGui, CoreStacksInStripsEqualTheInMemoryStack) {
  test::TempDir dir;
  const FrameCube cube = dotCube();
  const std::string path = writePrepared(dir, cube);
  NullProgress progress;
  CancelToken cancel;
  const pipeline::OutOfCoreCube ooc = pipeline::openOutOfCore({path}, {}, progress, cancel);
  EXPECT_EQ(ooc.shape.frames, kFrames);
  EXPECT_DOUBLE_EQ(ooc.meta.sigmaF, 0.05);
  // 2 MB: strips of a few rows (each with the overlap of the largest shift at kV).
  const Image strips = pipeline::stackOutOfCore(ooc, kV, 2u << 20, progress, cancel);
  const stack::StackResult whole = stack::stackIpsa(cube, kV);
  EXPECT_EQ(strips.pixels, whole.sum.pixels);
}

// The GUI's out-of-core tree search (pipeline::searchOutOfCore, a cube in tiles) re-scores its candidates by
// the exact statistic as the in-memory search does (searchWithMethod: tree_polish): the same candidates,
// cells and SNRs; the re-scoring reads the tiles that own them again, with progress to 1.
TEST(OutOfCoreGui, CoreTreeSearchInTilesReScoresAsInMemory) {
  test::TempDir dir;
  const FrameCube cube = dotCube();
  const std::string path = writePrepared(dir, cube);
  struct Said : ProgressSink {
    std::vector<std::pair<double, std::string>> said;
    void report(double f, std::string_view stage) override { said.emplace_back(f, std::string(stage)); }
  } said;
  CancelToken cancel;
  const pipeline::OutOfCoreCube ooc = pipeline::openOutOfCore({path}, {}, said, cancel);
  const search::VelocityGrid grid{{kV.vx + 0.03, kV.vy - 0.02}, 0.05, 9, 9};
  search::SearchParams params;
  params.method = search::SearchMethod::Tree;
  said.said.clear();
  const pipeline::OutOfCoreSearch tiled = pipeline::searchOutOfCore(ooc, grid, params, 90u << 20, said, cancel);
  std::printf("%zu tiles, %s\n", tiled.tiles, tiled.result.backendNote.c_str());
  ASSERT_GE(tiled.tiles, 2u) << "one tile: the test does not test the tiles";
  ASSERT_EQ(tiled.result.method, search::SearchMethod::Tree) << tiled.result.methodReason;
  EXPECT_NE(tiled.result.backendNote.find("re-scored"), std::string::npos) << tiled.result.backendNote;
  ASSERT_FALSE(said.said.empty());
  EXPECT_DOUBLE_EQ(said.said.back().first, 1.0);
  EXPECT_TRUE(std::any_of(said.said.begin(), said.said.end(),
                          [](const auto& s) { return s.second.find("re-scoring") != std::string::npos; }));
  search::FilteredCube fc;
  fc.frames = cube;
  fc.sigmaF = 0.05;
  fc.psfFwhmPx = 2.5;
  NullProgress quiet;
  const auto backend = search::makeCpuBackend();
  const search::SearchResult whole = search::searchWithMethod(*backend, fc, grid, params, quiet, cancel);
  ASSERT_FALSE(whole.candidates.empty());
  ASSERT_EQ(tiled.result.candidates.size(), whole.candidates.size());
  for (std::size_t k = 0; k < whole.candidates.size(); ++k) {
    const auto &a = tiled.result.candidates[k], &b = whole.candidates[k];
    EXPECT_EQ(a.x, b.x) << k;
    EXPECT_EQ(a.y, b.y) << k;
    EXPECT_DOUBLE_EQ(a.v.vx, b.v.vx) << k;
    EXPECT_DOUBLE_EQ(a.v.vy, b.v.vy) << k;
    EXPECT_NEAR(a.snr, b.snr, 1e-4 * b.snr) << k;
    EXPECT_EQ(a.nIn, b.nIn) << k;
  }
}

TEST(OutOfCoreGui, CorePlanOpenKeepsWhatFitsOpensPreparedOutOfCoreAndRefusesRawFrames) {
  test::TempDir dir;
  FrameCube small = test::movingDotCube(64, 64, 50, {2.0, 1.0}, 30, 30);
  const std::string raw = (dir / "raw.fits").string();
  io::writeCube(raw, small, {});
  CancelToken cancel;
  // 8 GB: everything fits.
  pipeline::OpenPlan plan = pipeline::planOpen({raw}, {}, std::size_t{8} << 30, 2, cancel);
  EXPECT_EQ(plan.mode, pipeline::OpenMode::InMemory);
  EXPECT_EQ(plan.shape.frames, 50u);
  // 50 MB: below the base of any estimate. Raw frames are refused, naming the CLI that pre-processes them
  // out of core.
  plan = pipeline::planOpen({raw}, {}, 50u << 20, 2, cancel);
  EXPECT_EQ(plan.mode, pipeline::OpenMode::Refused);
  EXPECT_FALSE(plan.prepared);
  EXPECT_NE(plan.reason.find("synthtrack-cli search"), std::string::npos) << plan.reason;
  EXPECT_NE(plan.reason.find("--keep-scratch"), std::string::npos) << plan.reason;
  EXPECT_NE(plan.reason.find("50 frames of 64 x 64 px"), std::string::npos) << plan.reason;
  // The same frames written as a prepared cube open out of core.
  const std::string prepared = writePrepared(dir, small);
  plan = pipeline::planOpen({prepared}, {}, 50u << 20, 2, cancel);
  EXPECT_EQ(plan.mode, pipeline::OpenMode::OutOfCore);
  EXPECT_TRUE(plan.prepared);
  EXPECT_GT(plan.need.total(), 50.0 * (1 << 20));
}

TEST(OutOfCoreGui, ACubeOverTheBudgetOpensOutOfCoreAndIsSearchedInTiles) {
  const auto start = std::chrono::steady_clock::now();
  OwnSettings settings;
  test::TempDir dir;
  const FrameCube cube = dotCube();
  const std::string path = writePrepared(dir, cube);
  std::shared_ptr<const Image> shownStack;  // what OutOfCoreController::stackReady gave, declared before `w`
  Velocity shownV;
  MainWindow w(servicesWithPlanOpen());
  w.resize(1366, 768);
  w.show();
  w.setScripted(true);  // errors go to the status bar, not to a modal box
  OutOfCoreController* ooc = OutOfCoreController::of(&w);
  ASSERT_NE(ooc, nullptr);
  EXPECT_THROW(ooc->setMemoryLimit("lots"), InputError);
  // The cube needs ~143 MB held in the GUI; a search tile of it ~85 MB.
  ooc->setMemoryLimit("100M");
  EXPECT_EQ(ooc->budget().bytes, 100u << 20);
  auto* label = w.findChild<QLabel*>("memory.label");
  ASSERT_NE(label, nullptr);
  EXPECT_TRUE(label->text().startsWith("memory budget 100")) << label->text().toStdString();

  w.openInputs({QString::fromStdString(path)});
  ASSERT_TRUE(test::waitFor([&] { return !w.jobs()->busy(); }, 30000));
  ASSERT_TRUE(w.observation()->prepared()) << w.statusBar()->currentMessage().toStdString();
  ASSERT_TRUE(ooc->active());
  EXPECT_TRUE(w.outOfCore());
  EXPECT_TRUE(label->text().contains("OUT OF CORE")) << label->text().toStdString();
  auto* banner = w.findChild<QLabel*>("memory.outOfCoreText");
  ASSERT_NE(banner, nullptr);
  EXPECT_TRUE(banner->isVisible());
  EXPECT_TRUE(banner->text().contains("Out of core")) << banner->text().toStdString();
  EXPECT_TRUE(banner->text().contains("1024 frames of 96 × 96 px")) << banner->text().toStdString();
  EXPECT_TRUE(banner->text().contains("memory budget of 100 MB")) << banner->text().toStdString();
  EXPECT_TRUE(banner->text().contains("unavailable")) << banner->text().toStdString();
  EXPECT_TRUE(w.statusBar()->currentMessage().startsWith("Opened out of core"))
      << w.statusBar()->currentMessage().toStdString();
  // The view: the mean of all frames, as in memory.
  const auto& raw = w.observation()->raw();
  ASSERT_EQ(raw->frameCount(), 1u);
  const stack::StackResult still = stack::stackIpsa(cube, Velocity{});
  for (std::size_t k = 0; k < still.sum.size(); k += 97)
    EXPECT_NEAR(raw->frame(0)[k], still.sum.pixels[k] / kFrames, 1e-6);
  test::waitFor([] { return false; }, 300);  // the layouts settle (the banner's height, the labels' widths)
  if (const QByteArray shots = qgetenv("ST_OUT_OF_CORE_SCREENSHOT_DIR"); !shots.isEmpty()) {
    QDir().mkpath(QString::fromLocal8Bit(shots));
    EXPECT_TRUE(w.grab().save(QString::fromLocal8Bit(shots) + "/out_of_core_banner.png"));
  }

  search::SearchParams params = w.searchPanel()->params();
  params.method = search::SearchMethod::Exact;
  w.searchPanel()->setParams(params);
  w.searchPanel()->setGridPxS(kV, 1.0, 0.5);
  // Cancelled at once: the job stops, no result.
  w.runSearch();
  ASSERT_TRUE(w.jobs()->busy());
  EXPECT_EQ(w.jobs()->currentKind(), JobKind::Search);
  w.jobs()->cancel();
  ASSERT_TRUE(test::waitFor([&] { return !w.jobs()->busy(); }, 5000));
  EXPECT_FALSE(w.observation()->result());

  // The search, with the out-of-core stack of the best candidate that selecting it asks for.
  QObject::connect(ooc, &OutOfCoreController::stackReady, &w,
                   [&](const std::shared_ptr<const Image>& sum, Velocity v, double) {
                     shownStack = sum;
                     shownV = v;
                   });
  w.runSearch();
  ASSERT_TRUE(w.jobs()->busy());
  ASSERT_TRUE(test::waitFor([&] { return !w.jobs()->busy(); }, 60000));
  const QString status = w.statusBar()->currentMessage();
  ASSERT_TRUE(w.observation()->result()) << status.toStdString();
  EXPECT_TRUE(status.startsWith("Search out of core")) << status.toStdString();
  std::printf("%s\n", status.toLocal8Bit().constData());
  const auto& result = *w.observation()->result();
  ASSERT_FALSE(result.candidates.empty());
  // The same best candidate as the in-memory core search of the whole cube.
  search::FilteredCube whole;
  whole.frames = cube;
  whole.sigmaF = 0.05;
  whole.psfFwhmPx = 2.5;
  auto backend = search::makeCpuBackend();
  NullProgress progress;
  CancelToken cancel;
  const search::SearchResult inMemory =
      search::searchWithMethod(*backend, whole, w.searchPanel()->grid(), params, progress, cancel);
  ASSERT_FALSE(inMemory.candidates.empty());
  EXPECT_EQ(result.candidates.size(), inMemory.candidates.size());
  EXPECT_EQ(result.candidates[0].x, inMemory.candidates[0].x);
  EXPECT_EQ(result.candidates[0].y, inMemory.candidates[0].y);
  EXPECT_EQ(result.candidates[0].v, inMemory.candidates[0].v);
  EXPECT_NEAR(result.candidates[0].snr, inMemory.candidates[0].snr, 1e-6 * inMemory.candidates[0].snr);
  EXPECT_EQ(result.candidates[0].x, 48);
  EXPECT_EQ(result.candidates[0].y, 40);
  EXPECT_EQ(result.candidates[0].v, kV);
  // The best candidate is selected; its stack, summed in strips in a worker, equals the in-memory one.
  EXPECT_EQ(w.observation()->selected(), std::optional<int>(0));
  ASSERT_TRUE(test::waitFor([&] { return shownStack != nullptr; }, 20000));
  EXPECT_EQ(shownV, kV);
  EXPECT_EQ(shownStack->pixels, stack::stackIpsa(cube, kV).sum.pixels);
  // What needs the cube in memory says so, and does not run on the 16 x 16 corner the window holds.
  EXPECT_FALSE(w.candidateInspector()->busy());
  EXPECT_TRUE(w.candidateInspector()->statusText().contains("Unavailable out of core"))
      << w.candidateInspector()->statusText().toStdString();
  w.fitPanel()->fitSelected();
  EXPECT_FALSE(w.jobs()->busy());
  EXPECT_TRUE(w.fitPanel()->statusText().contains("unavailable out of core"))
      << w.fitPanel()->statusText().toStdString();

  const double elapsedS =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("out-of-core GUI test: %.1f s\n", elapsedS);
  EXPECT_LT(elapsedS, 60.0);
}

// Raw frames whose in-memory pre-processing does not fit are pre-processed out of core in the load job's
// worker (core's planRawOutOfCore + preprocessRawOutOfCore, strips of rows) into a scratch cube that opens
// out of core; the search finds the simulated asteroid where the in-memory core pipeline does; the scratch
// cube goes when another observation is opened. A budget too small for even one strip fails the load with
// the need and the budget.
TEST(OutOfCoreGui, RawFramesOverTheBudgetArePreProcessedOutOfCoreInTheWorker) {
  OwnSettings settings;
  test::TempDir dir;
  NullProgress progress;
  CancelToken cancel;
  sim::SimParams sp = sim::preset("small");
  sim::resize(sp, 128, 512, 100);
  const sim::SimResult simulated = sim::simulate(sp, 5, progress, cancel);
  ASSERT_FALSE(simulated.truth.objects.empty());
  const sim::TruthObject& truth = simulated.truth.objects.front();
  const std::string raw = (dir / "raw.fits").string();
  io::writeCube(raw, simulated.cube, simulated.cube.header);
  QSettings().setValue("memory/scratch", QString::fromStdString(dir.path().string()));
  CoreServices services = servicesWithPlanOpen();
  services.loadFrames = [](const std::vector<std::string>& inputs, ProgressSink& p, CancelToken& c) {
    return io::loadFrames(inputs, {}, p, c);
  };
  MainWindow w(services);
  w.show();
  w.setScripted(true);
  OutOfCoreController* ooc = OutOfCoreController::of(&w);
  // 128 x 512 x 100 raw frames need ~140 MB to pre-process in memory; strips of 256 rows fit 96 MB.
  ooc->setMemoryLimit("96M");
  w.openInputs({QString::fromStdString(raw)});
  ASSERT_TRUE(w.jobs()->busy());  // the GUI thread only started the job
  ASSERT_TRUE(test::waitFor([&] { return !w.jobs()->busy(); }, 120000));
  const QString opened = w.statusBar()->currentMessage();
  ASSERT_TRUE(ooc->active()) << opened.toStdString();
  EXPECT_TRUE(opened.contains("Opened out of core")) << opened.toStdString();
  ASSERT_FALSE(ooc->scratchCube().empty());
  EXPECT_TRUE(std::filesystem::exists(ooc->scratchCube()));
  EXPECT_EQ(std::filesystem::path(ooc->scratchCube()).parent_path(), dir.path());
  ASSERT_TRUE(w.observation()->prepared());
  const std::string summary = w.observation()->prepared()->summary;
  EXPECT_NE(summary.find("pre-processed out of core just now"), std::string::npos) << summary;
  EXPECT_NE(summary.find("pre-processing out of core: 2 strips"), std::string::npos) << summary;
  EXPECT_TRUE(w.findChild<QLabel*>("memory.outOfCoreText")->isVisible());

  const Velocity v{truth.vxPxPerS, truth.vyPxPerS};
  search::SearchParams params = w.searchPanel()->params();
  params.method = search::SearchMethod::Exact;
  w.searchPanel()->setParams(params);
  w.searchPanel()->setGridPxS(v, 1.0, 0.25);
  w.runSearch();
  ASSERT_TRUE(test::waitFor([&] { return !w.jobs()->busy(); }, 120000));
  ASSERT_TRUE(w.observation()->result()) << w.statusBar()->currentMessage().toStdString();
  const auto& result = *w.observation()->result();
  ASSERT_FALSE(result.candidates.empty());
  // The in-memory core pipeline on the same frames and grid.
  pipeline::PreprocessParams pp;
  pp.keepZeroBiased = false;
  const pipeline::Prepared whole = pipeline::preprocess(simulated.cube, pp, progress, cancel);
  auto backend = search::makeCpuBackend();
  const search::SearchResult inMemory =
      search::searchWithMethod(*backend, whole.filtered, w.searchPanel()->grid(), params, progress, cancel);
  ASSERT_FALSE(inMemory.candidates.empty());
  const search::Candidate& a = inMemory.candidates[0];
  const search::Candidate& b = result.candidates[0];
  std::printf("asteroid at (%.1f, %.1f): in memory (%d, %d) SNR %.2f, out of core (%d, %d) SNR %.2f\n",
              truth.xRefPx, truth.yRefPx, a.x, a.y, a.snr, b.x, b.y, b.snr);
  EXPECT_NEAR(a.x, truth.xRefPx, 1.5);
  EXPECT_NEAR(a.y, truth.yRefPx, 1.5);
  EXPECT_NEAR(b.x, a.x, 1);
  EXPECT_NEAR(b.y, a.y, 1);
  EXPECT_NEAR(b.v.vx, a.v.vx, 0.26);
  EXPECT_NEAR(b.v.vy, a.v.vy, 0.26);
  EXPECT_NEAR(b.snr, a.snr, 0.05 * a.snr);

  // The same frames opened again: a new scratch cube, the first removed when the second is applied.
  const std::string first = ooc->scratchCube();
  w.openInputs({QString::fromStdString(raw)});
  ASSERT_TRUE(test::waitFor([&] { return !w.jobs()->busy(); }, 120000));
  ASSERT_TRUE(ooc->active()) << w.statusBar()->currentMessage().toStdString();
  EXPECT_NE(ooc->scratchCube(), first);
  EXPECT_FALSE(std::filesystem::exists(first));
  EXPECT_TRUE(std::filesystem::exists(ooc->scratchCube()));

  // Another observation: the scratch cube is removed.
  const std::string scratch = ooc->scratchCube();
  ooc->setMemoryLimit("");
  const std::string small = (dir / "small.fits").string();
  io::writeCube(small, test::movingDotCube(32, 32, 8, {1.0, 0.0}, 10, 10), {});
  w.openInputs({QString::fromStdString(small)});
  ASSERT_TRUE(test::waitFor([&] { return !w.jobs()->busy(); }, 20000));
  EXPECT_FALSE(ooc->active()) << w.statusBar()->currentMessage().toStdString();
  ASSERT_TRUE(w.observation()->raw());
  EXPECT_EQ(w.observation()->raw()->width(), 32);
  EXPECT_FALSE(std::filesystem::exists(scratch));

  // Not even a strip of rows fits: the load fails naming the need and the budget.
  ooc->setMemoryLimit("50M");
  w.openInputs({QString::fromStdString(raw)});
  ASSERT_TRUE(test::waitFor([&] { return !w.jobs()->busy(); }, 20000));
  const QString status = w.statusBar()->currentMessage();
  EXPECT_FALSE(ooc->active());
  EXPECT_TRUE(status.contains("pre-processing out of core (the smallest strip of rows")) << status.toStdString();
  EXPECT_TRUE(status.contains("Run > Memory limit")) << status.toStdString();
}

ST_UI_TEST_MAIN_ISOLATED()

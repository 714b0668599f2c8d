// Plate solving from the GUI (issue 15 item 5): frames without a WCS get a banner above the image that says
// so and offers "Plate solve"; clicking it runs astrometry.net's solve-field (here a stand-in script, as in
// tests/core/test_plate_solve.cpp, so no index files are needed) as a cancellable job, and the solved WCS is
// attached to the observation (RA/Dec, the compass and the reports use it). A missing solve-field is reported
// readably in the banner; Cancel stops a running solve promptly; the script's --plate-solve does the same.
#include <gtest/gtest.h>

#include <sys/stat.h>

#include <QAction>
#include <QCheckBox>
#include <QDir>
#include <QLabel>
#include <QPushButton>
#include <QStatusBar>
#include <QTest>
#include <chrono>
#include <fstream>

#include "figure_dialog.hpp"
#include "job_runner.hpp"
#include "main_window.hpp"
#include "plate_solve_settings.hpp"
#include "script_runner.hpp"
#include "session_snapshot.hpp"
#include "session_controller.hpp"
#include "st/session/session.hpp"
#include "st/io/wcs.hpp"
#include "st/io/xylist.hpp"
#include "test_support.hpp"
#include "ui_test_support.hpp"

using namespace st;
using namespace st::ui;
using nlohmann::json;

namespace {

/// Ten frames 128 x 96 of eight static Gaussian stars on a background of 100 with noise of 1 (fixed seed).
FrameCube starField() {
  FrameCube cube(128, 96, 10);
  const double stars[8][3] = {{20, 20, 400}, {100, 30, 300}, {60, 70, 250}, {30, 80, 200},
                              {110, 80, 350}, {75, 15, 150}, {45, 45, 500}, {90, 55, 180}};
  std::uint32_t seed = 12345;
  const auto noise = [&seed] {  // sum of 12 uniforms - 6: unit variance
    double s = 0;
    for (int k = 0; k < 12; ++k) {
      seed = seed * 1664525u + 1013904223u;
      s += (seed >> 8) / 16777216.0;
    }
    return s - 6.0;
  };
  for (std::size_t n = 0; n < cube.frameCount(); ++n) {
    cube.info()[n].mjdMid = 60000.0 + n * 1.0 / 86400.0;
    float* f = cube.frame(n);
    for (int y = 0; y < 96; ++y)
      for (int x = 0; x < 128; ++x) {
        double v = 100.0 + noise();
        for (const auto& s : stars)
          v += s[2] * std::exp(-((x - s[0]) * (x - s[0]) + (y - s[1]) * (y - s[1])) / (2 * 1.5 * 1.5));
        f[y * 128 + x] = static_cast<float>(v);
      }
  }
  return cube;
}

CoreServices services() {
  CoreServices s = test::fakeServices(starField());
  s.pixelToSky = [](const FrameCube& cube, double x, double y) -> std::optional<std::pair<double, double>> {
    if (!cube.wcs) return std::nullopt;
    const Wcs::Sky sky = cube.wcs->pixelToSky(x, y);
    return std::make_pair(sky.raDeg, sky.decDeg);
  };
  return s;
}

std::string script(const test::TempDir& dir, const std::string& name, const std::string& body) {
  const auto path = dir / name;
  std::ofstream(path) << "#!/bin/sh\n" << body;
  ::chmod(path.c_str(), 0755);
  return path.string();
}

/// A stand-in solve-field that "solves" the field as RA 150, Dec 2 at the 1-based pixel (64.5, 48.5), 1.5"/px
/// (copies that WCS to --dir/--out.wcs, as solve-field writes it), and a folder with an index file's name.
struct FakeAstrometry {
  test::TempDir dir;
  QString solveField;
  QString indexDir;
  FakeAstrometry() {
    // (Each test process has its own settings file, runUiTests: one test's solve-field, a 30 s sleep, was
    // read by another at -j2 before, 2026-11-27.)
    FitsHeader wcs;
    test::setTanWcs(wcs, 150.0, 2.0, 64.5, 48.5, 1.5);
    const std::string wcsFile = (dir / "truth.wcs").string();
    io::writeHeaderFile(wcsFile, wcs);
    solveField = QString::fromStdString(script(
        dir, "solve-field",
        "sleep 0.3\nwhile [ $# -gt 0 ]; do case \"$1\" in --dir) d=\"$2\"; shift;; --out) o=\"$2\"; shift;; "
        "esac; shift; done\ncp '" +
            wcsFile + "' \"$d/$o.wcs\" && touch \"$d/$o.solved\"\n"
                      "echo 'Field 1: solved with index index-4200.fits.'\n"));
    std::filesystem::create_directories(dir / "index");
    std::ofstream(dir / "index" / "index-4200.fits") << "";
    indexDir = QString::fromStdString((dir / "index").string());
  }
  void use(const QString& program) const {
    PlateSolveSettings s;
    s.solveField = program;
    s.indexDirs = {indexDir};
    s.timeLimitS = 30;
    s.save();
  }
};

QWidget* banner(MainWindow& w) {
  return w.findChild<QWidget*>("wcs.banner");
}
QString bannerText(MainWindow& w) {
  return w.findChild<QLabel*>("wcs.text")->text();
}

void openAndPrepare(MainWindow& w) {
  w.resize(1366, 768);
  w.show();
  w.openDemo();
  ASSERT_TRUE(test::waitFor([&] { return w.observation()->prepared() && !w.jobs()->busy(); }));
}

}  // namespace

TEST(PlateSolveGui, TheBannerOffersPlateSolvingAndTheSolvedWcsIsUsed) {
  FakeAstrometry astrometry;
  astrometry.use(astrometry.solveField);
  MainWindow w(services());
  openAndPrepare(w);
  ASSERT_FALSE(w.observation()->raw()->wcs);
  ASSERT_TRUE(banner(w)->isVisible());
  EXPECT_TRUE(bannerText(w).contains("No WCS")) << bannerText(w).toStdString();
  EXPECT_TRUE(bannerText(w).contains("ADES")) << bannerText(w).toStdString();
  auto* action = w.findChild<QAction*>("action.plateSolve");
  ASSERT_NE(action, nullptr);
  EXPECT_TRUE(action->isEnabled());
  QDir().mkpath("ui_screens");
  w.saveScreenshot("ui_screens/plate_solve_banner.png");

  QTest::mouseClick(w.findChild<QPushButton*>("wcs.solve"), Qt::LeftButton);
  EXPECT_TRUE(w.jobs()->busy());
  EXPECT_EQ(w.jobs()->currentKind(), JobKind::PlateSolve);
  EXPECT_TRUE(bannerText(w).contains("Plate solving")) << bannerText(w).toStdString();
  ASSERT_TRUE(test::waitFor([&] { return !w.jobs()->busy(); }, 30000));

  const auto& raw = w.observation()->raw();
  ASSERT_TRUE(raw->wcs) << w.statusBar()->currentMessage().toStdString() << " / "
                        << bannerText(w).toStdString();
  EXPECT_FALSE(banner(w)->isVisible());
  EXPECT_FALSE(action->isEnabled());
  EXPECT_NEAR(*w.observation()->plateScale(), 1.5, 1e-6);
  const Wcs::Sky centre = raw->wcs->pixelToSky(63.5, 47.5);  // 0-based = CRPIX - 1
  EXPECT_NEAR(centre.raDeg, 150.0, 1e-9);
  EXPECT_NEAR(centre.decDeg, 2.0, 1e-9);
  // The pre-processed cube (what fits and stacks use) and the header (a later pre-processing) carry it.
  EXPECT_TRUE(w.observation()->prepared()->filtered->frames.wcs);
  EXPECT_TRUE(raw->header.getString("CTYPE1").has_value());
  EXPECT_TRUE(w.plateSolveSummary().contains("RA 150.000000")) << w.plateSolveSummary().toStdString();
  EXPECT_TRUE(w.plateSolveSummary().contains("sources of frame 0")) << w.plateSolveSummary().toStdString();
  EXPECT_TRUE(w.statusBar()->currentMessage().startsWith("WCS plate-solved"))
      << w.statusBar()->currentMessage().toStdString();
  // The compass of the figures can now be drawn.
  FigureDialog* d = w.figureDialog();
  d->refreshSources();
  for (auto* box : d->findChildren<QCheckBox*>())
    if (box->text().startsWith("N/E compass")) {
      EXPECT_TRUE(box->isEnabled());
      EXPECT_EQ(box->text(), "N/E compass");
    }
  w.saveScreenshot("ui_screens/plate_solve_solved.png");
}

// The solved WCS is part of the session: the file records it, and reopening the session (frames still without
// a WCS of their own) attaches it again before pre-processing, so RA/Dec work without solving again.
TEST(PlateSolveGui, TheSolvedWcsIsSavedInTheSessionAndAttachedOnReopening) {
  FakeAstrometry astrometry;
  astrometry.use(astrometry.solveField);
  QString path;
  {
    MainWindow w(services());
    openAndPrepare(w);
    ASSERT_TRUE(w.runPlateSolve());
    ASSERT_TRUE(test::waitFor([&] { return !w.jobs()->busy(); }, 30000));
    ASSERT_TRUE(w.observation()->raw()->wcs);
    ASSERT_TRUE(w.observation()->solvedWcs());
    ASSERT_TRUE(w.session()->autosaver()->flush());
    path = w.session()->path();
    ASSERT_FALSE(path.isEmpty());
  }
  const session::Session saved = session::SessionStore(path.toStdString()).load();
  ASSERT_TRUE(saved.parameters.contains("plate_solve")) << saved.parameters.dump();
  EXPECT_NEAR(saved.parameters["plate_solve"]["scale_arcsec_px"].get<double>(), 1.5, 1e-6);

  // Reopened in a window whose solve-field would fail: nothing is solved again.
  astrometry.use("/nonexistent/solve-field");
  MainWindow w2(services());
  w2.resize(1366, 768);
  w2.show();
  w2.openSession(path);
  ASSERT_TRUE(test::waitFor([&] { return w2.observation()->prepared() && !w2.jobs()->busy(); }, 30000));
  const auto& raw = w2.observation()->raw();
  ASSERT_TRUE(raw->wcs) << w2.statusBar()->currentMessage().toStdString();
  const Wcs::Sky centre = raw->wcs->pixelToSky(63.5, 47.5);
  EXPECT_NEAR(centre.raDeg, 150.0, 1e-9);
  EXPECT_NEAR(centre.decDeg, 2.0, 1e-9);
  EXPECT_NEAR(*w2.observation()->plateScale(), 1.5, 1e-6);
  EXPECT_TRUE(w2.observation()->prepared()->filtered->frames.wcs);
  EXPECT_TRUE(raw->header.getString("CTYPE1").has_value());
  EXPECT_FALSE(banner(w2)->isVisible());
  w2.saveScreenshot("ui_screens/plate_solve_reopened.png");
  // Still recorded as solved, so the next save keeps it.
  ASSERT_TRUE(w2.observation()->solvedWcs());
  ASSERT_TRUE(w2.session()->autosaver()->flush());
  EXPECT_TRUE(session::SessionStore(path.toStdString()).load().parameters.contains("plate_solve"));
}

// A damaged "plate_solve" member is an error naming the file and the key, not a silent loss of the WCS.
TEST(PlateSolveGui, ADamagedSavedWcsIsAnErrorNamingTheKey) {
  session::Session s;
  s.parameters["plate_solve"] = {{"scale_arcsec_px", 1.5}, {"wcs_cards", {{{"key", "CTYPE1"}}}}};
  try {
    (void)restoreSnapshot(s, {}, "/tmp/x.json");
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("/tmp/x.json: parameters.plate_solve.wcs_cards"), std::string::npos)
        << e.what();
  }
  s.parameters["plate_solve"] = {{"scale_arcsec_px", 1.5}, {"wcs_cards", json::array()}};
  EXPECT_THROW((void)restoreSnapshot(s, {}, "/tmp/x.json"), InputError);
}

TEST(PlateSolveGui, AMissingSolveFieldIsReportedInTheBanner) {
  FakeAstrometry astrometry;
  astrometry.use("/nonexistent/solve-field");
  MainWindow w(services());
  openAndPrepare(w);
  ASSERT_TRUE(w.runPlateSolve());
  ASSERT_TRUE(test::waitFor([&] { return !w.jobs()->busy(); }, 30000));
  EXPECT_FALSE(w.observation()->raw()->wcs);
  EXPECT_TRUE(banner(w)->isVisible());
  const QString text = bannerText(w);
  EXPECT_TRUE(text.contains("Plate solving failed")) << text.toStdString();
  EXPECT_TRUE(text.contains("solve-field, which was not found")) << text.toStdString();
  EXPECT_TRUE(text.contains("astrometry.net")) << text.toStdString();
  EXPECT_EQ(w.findChild<QPushButton*>("wcs.solve")->text(), "Try again");
  w.saveScreenshot("ui_screens/plate_solve_failed.png");
}

TEST(PlateSolveGui, CancelStopsARunningSolvePromptly) {
  FakeAstrometry astrometry;
  astrometry.use(QString::fromStdString(script(astrometry.dir, "slow-solve-field", "sleep 30\n")));
  MainWindow w(services());
  openAndPrepare(w);
  ASSERT_TRUE(w.runPlateSolve());
  QTest::qWait(500);  // solve-field is running
  ASSERT_TRUE(w.jobs()->busy());
  QPushButton* cancel = nullptr;
  for (auto* b : w.statusBar()->findChildren<QPushButton*>())
    if (b->text() == "Cancel") cancel = b;
  ASSERT_NE(cancel, nullptr);
  ASSERT_TRUE(cancel->isVisible());
  const auto t0 = std::chrono::steady_clock::now();
  QTest::mouseClick(cancel, Qt::LeftButton);
  ASSERT_TRUE(test::waitFor([&] { return !w.jobs()->busy(); }, 10000));
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 3.0);
  EXPECT_FALSE(w.observation()->raw()->wcs);
  EXPECT_TRUE(bannerText(w).contains("cancelled")) << bannerText(w).toStdString();
}

TEST(PlateSolveGui, TheScriptPlateSolvesBeforeTheSearch) {
  FakeAstrometry astrometry;
  astrometry.use("/nonexistent/solve-field");  // the script's own options replace it
  MainWindow w(services());
  w.resize(1366, 768);
  w.show();
  ScriptOptions script;
  script.demo = true;
  script.plateSolve = true;
  script.solveField = astrometry.solveField;
  script.indexDirs = {astrometry.indexDir};
  bool finished = false, good = false;
  ScriptRunner runner(&w);
  QObject::connect(&runner, &ScriptRunner::finished, [&](bool ok) {
    finished = true;
    good = ok;
  });
  runner.run(script);
  ASSERT_TRUE(test::waitFor([&] { return finished; }, 30000));
  EXPECT_TRUE(good);
  ASSERT_TRUE(w.observation()->raw()->wcs);
  EXPECT_EQ(PlateSolveSettings::load().solveField, astrometry.solveField);
}

ST_UI_TEST_MAIN_ISOLATED()

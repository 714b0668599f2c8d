// The search panel's settings in the session file (issue: reopening a session did not restore them): grid
// (exactly, also a step the spin boxes cannot show), threshold by SNR or FAP, method, backend and velocity
// unit come back in a new window; a change made by hand after the last search is saved too; a file from an
// older build without these keys opens with the panel's defaults. Demo autosaves do not pile up: each demo
// run used to leave one more demo.synthtrack-session-N.json in the application's folder; now the newest
// kDemoAutosavesKept stay, and a file a person saved there (Save session as…) is never deleted.
#include <gtest/gtest.h>

#include <QAbstractSpinBox>
#include <QComboBox>
#include <QDir>
#include <QDoubleSpinBox>
#include <QLineEdit>
#include <QRadioButton>
#include <QStandardPaths>
#include <QTest>
#include <filesystem>
#include <fstream>

#include "candidate_inspector.hpp"
#include "job_runner.hpp"
#include "main_window.hpp"
#include "search_panel.hpp"
#include "session_controller.hpp"
#include "test_support.hpp"
#include "ui_test_support.hpp"

using namespace st;
using namespace st::ui;

namespace {

/// A moving dot with a plate scale (so deg/day and "/min are offered), loadable from any existing path.
CoreServices services() {
  FrameCube cube = test::movingDotCube(48, 48, 12, {4.0, -2.0}, 20, 24);
  cube.plateScaleArcsecPerPx = 1.5;
  CoreServices s = test::fakeServices(cube);
  auto shared = std::make_shared<const FrameCube>(cube);
  s.loadFrames = [shared](const std::vector<std::string>& inputs, ProgressSink&, CancelToken&) {
    for (const auto& p : inputs)
      if (!std::filesystem::exists(p)) throw InputError("no such file '" + p + "'");
    return *shared;
  };
  return s;
}

bool idle(MainWindow& w) {
  return !w.jobs()->busy() && !w.candidateInspector()->busy();
}

template <typename T>
T* child(SearchPanel* panel, const QString& text = {}) {
  for (T* w : panel->findChildren<T*>()) {
    if constexpr (std::is_same_v<T, QComboBox>) {
      if (w->findText(text) >= 0) return w;
    } else if constexpr (std::is_same_v<T, QRadioButton>) {
      if (w->text().startsWith(text)) return w;
    } else if (!qobject_cast<QAbstractSpinBox*>(w->parent())) {  // the FAP field, not a spin box's editor
      return w;
    }
  }
  return nullptr;
}

/// The SNR spin box: the one whose range ends at 100 with 2 decimals (the grid's have 4).
QDoubleSpinBox* snrSpin(SearchPanel* panel) {
  for (auto* s : panel->findChildren<QDoubleSpinBox*>())
    if (s->decimals() == 2) return s;
  return nullptr;
}

void openAndWait(MainWindow& w, const std::string& input) {
  w.openInputs({QString::fromStdString(input)});
  ASSERT_TRUE(test::waitFor([&] { return w.observation()->prepared() && idle(w); }));
}

}  // namespace

TEST(SessionSearchSettings, ReopeningRestoresTheSearchPanel) {
  test::TempDir dir;
  const std::string input = (dir / "obs.fits").string();
  std::ofstream(input) << "fake";
  QString path;
  const Velocity centre{3.0, -1.5};
  const double step = 1.0 / 3.0;  // 0.3333 px/s in the spin box: the grid must keep 1/3 exactly
  {
    MainWindow w1(services());
    w1.show();
    openAndWait(w1, input);
    SearchPanel* panel = w1.searchPanel();
    child<QComboBox>(panel, "px/s")->setCurrentIndex(0);  // px/s instead of the default deg/day
    panel->setGridPxS(centre, 2.0, step);
    w1.runSearch();
    ASSERT_TRUE(test::waitFor([&] { return w1.observation()->result() && idle(w1); }));
    // Changed after the search, by hand: threshold by FAP, SNR value, method, backend.
    snrSpin(panel)->setValue(8.5);
    child<QLineEdit>(panel)->setText("0.001");
    child<QRadioButton>(panel, "FAP")->setChecked(true);
    panel->setMethod("tree");
    QComboBox* backend = child<QComboBox>(panel, "CPU");
    backend->setCurrentIndex(backend->findText("CPU"));
    path = w1.session()->path();
    ASSERT_TRUE(w1.session()->autosaver()->flush());
  }
  MainWindow w2(services());
  w2.show();
  w2.openSession(path);
  ASSERT_TRUE(test::waitFor([&] { return w2.observation()->result() && idle(w2); }));
  SearchPanel* panel = w2.searchPanel();
  const search::VelocityGrid g = panel->grid();
  EXPECT_EQ(g.centre.vx, centre.vx);
  EXPECT_EQ(g.centre.vy, centre.vy);
  EXPECT_EQ(g.stepPxS, step);
  EXPECT_EQ(g.nvx, 13);
  EXPECT_EQ(g.nvy, 13);
  const search::SearchParams p = panel->params();
  EXPECT_EQ(p.snrThreshold, 8.5);
  ASSERT_TRUE(p.targetFap.has_value());
  EXPECT_DOUBLE_EQ(*p.targetFap, 0.001);
  EXPECT_EQ(p.method, st::search::SearchMethod::Tree);
  EXPECT_EQ(panel->backendKind(), BackendKind::Cpu);
  EXPECT_EQ(w2.observation()->unit(), VelocityUnit::PxPerS);
  EXPECT_EQ(child<QComboBox>(panel, "px/s")->currentText(), "px/s");  // the panel shows the saved unit
  // Reopening saves nothing by itself, and the restored settings are what a new save writes.
  const session::Session saved = w2.session()->currentSession();
  EXPECT_EQ(saved.parameters["search"]["method"], "tree");
  EXPECT_EQ(saved.parameters["search"]["target_fap"], 0.001);
  EXPECT_EQ(saved.parameters["search"]["backend"], "cpu");
  EXPECT_EQ(saved.parameters["search"]["grid"]["step_px_s"], step);
}

TEST(SessionSearchSettings, AnOlderFileWithoutTheKeysOpensWithDefaults) {
  test::TempDir dir;
  const std::string input = (dir / "obs.fits").string();
  std::ofstream(input) << "fake";
  // A session as an older build wrote it: inputs and a grid, no threshold, method, backend or unit.
  session::Session old;
  old.inputs = {input};
  old.parameters["search"] = {
      {"grid",
       {{"centre_vx_px_s", 1.0}, {"centre_vy_px_s", 0.5}, {"step_px_s", 0.25}, {"nvx", 9}, {"nvy", 9}}}};
  const std::string file = (dir / "old.synthtrack-session.json").string();
  session::SessionStore(file).save(old);

  MainWindow w(services());
  w.show();
  SearchPanel* panel = w.searchPanel();
  // Settings left over from earlier work in this window must not survive the opening.
  snrSpin(panel)->setValue(11.0);
  child<QRadioButton>(panel, "FAP")->setChecked(true);
  panel->setMethod("exact");
  child<QComboBox>(panel, "CPU")->setCurrentIndex(1);
  w.openSession(QString::fromStdString(file));
  ASSERT_TRUE(test::waitFor([&] { return w.session()->path() == QString::fromStdString(file) && idle(w); }));
  const search::SearchParams p = panel->params();
  EXPECT_EQ(p.snrThreshold, search::SearchParams{}.snrThreshold);
  EXPECT_FALSE(p.targetFap.has_value());
  EXPECT_EQ(p.method, st::search::SearchMethod::Auto);
  EXPECT_EQ(panel->backendKind(), BackendKind::Auto);
  const search::VelocityGrid g = panel->grid();
  EXPECT_EQ(g.stepPxS, 0.25);
  EXPECT_EQ(g.nvx, 9);
  EXPECT_EQ(g.centre.vx, 1.0);
  // No unit in the file: the window's default for an observation with a plate scale, shown and used alike.
  EXPECT_EQ(w.observation()->unit(), VelocityUnit::DegPerDay);
  EXPECT_EQ(child<QComboBox>(panel, "px/s")->currentText(), "deg/day");
}

TEST(SessionSearchSettings, DemoAutosavesDoNotPileUp) {
  const QString folder = QStandardPaths::writableLocation(QStandardPaths::AppDataLocation) + "/sessions";
  QDir(folder).removeRecursively();
  QDir().mkpath(folder);
  // Files a person saved in that folder, one with a demo autosave's name: never deleted.
  const QString mine = folder + "/demo.synthtrack-session-40.json";
  const QString other = folder + "/my-demo-notes.json";
  {
    MainWindow w(services());
    w.show();
    w.openDemo();
    ASSERT_TRUE(test::waitFor([&] { return w.observation()->prepared() && idle(w); }));
    w.session()->saveAs(mine);
    ASSERT_TRUE(w.session()->autosaver()->flush());
  }
  std::ofstream(other.toStdString()) << "{}";
  constexpr int kRuns = 9;
  for (int run = 0; run < kRuns; ++run) {
    MainWindow w(services());
    w.show();
    w.openDemo();
    ASSERT_TRUE(test::waitFor([&] { return w.observation()->prepared() && idle(w); }));
    ASSERT_TRUE(w.session()->autosaver()->flush());
    EXPECT_TRUE(QFileInfo::exists(w.session()->path()));
    QTest::qWait(20);  // distinct modification times
  }
  QStringList autosaves = QDir(folder).entryList({"demo.synthtrack-session*.json"}, QDir::Files);
  autosaves.removeAll("demo.synthtrack-session-40.json");
  EXPECT_EQ(autosaves.size(), kDemoAutosavesKept) << autosaves.join(", ").toStdString();
  EXPECT_TRUE(QFileInfo::exists(mine));
  EXPECT_TRUE(QFileInfo::exists(other));
  // The person's file is a demo session without the autosave mark.
  const session::Session kept = session::SessionStore(mine.toStdString()).load();
  EXPECT_TRUE(kept.parameters["observation"]["demo"].get<bool>());
  EXPECT_FALSE(kept.parameters["observation"].contains("demo_autosave"));
}

TEST(SessionSearchSettings, PruningKeepsLockedUnmarkedAndUnreadableFiles) {
  test::TempDir dir;
  const QString folder = QString::fromStdString(dir.path().string());
  auto write = [&](const QString& name, const std::string& text) {
    std::ofstream((folder + "/" + name).toStdString()) << text;
    QTest::qWait(15);
  };
  const std::string marked = R"({"parameters": {"observation": {"demo": true, "demo_autosave": true}}})";
  for (int i = 2; i <= 8; ++i)
    write(QString("demo.synthtrack-session-%1.json").arg(i), marked);
  write("demo.synthtrack-session-20.json", R"({"parameters": {"observation": {"demo": true}}})");
  write("demo.synthtrack-session-21.json", "not json");
  write("demo.synthtrack-session-2.json.lock", "");
  SessionLock held;  // another window works on -3
  ASSERT_TRUE(held.acquire(folder + "/demo.synthtrack-session-3.json"));
  const QString current = folder + "/demo.synthtrack-session.json";
  const QStringList removed = pruneDemoAutosaves(folder, current, 3);
  // Newest marked first: -8, -7 kept (keep - 1 besides the current one); -6 .. -2 go, except the locked -3.
  QStringList names;
  for (const auto& p : removed)
    names << QFileInfo(p).fileName();
  names.sort();
  EXPECT_EQ(names, QStringList({"demo.synthtrack-session-2.json", "demo.synthtrack-session-4.json",
                                "demo.synthtrack-session-5.json", "demo.synthtrack-session-6.json"}));
  for (const char* kept : {"-3", "-7", "-8", "-20", "-21"})
    EXPECT_TRUE(QFileInfo::exists(folder + "/demo.synthtrack-session" + kept + ".json")) << kept;
}

ST_UI_TEST_MAIN_ISOLATED()

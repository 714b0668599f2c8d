// The Injection recovery dialog (Run menu), offscreen, on a hand-made truth file and candidates: 4 injected
// movers, 3 found (one 1.5 px off), one missed, one false alarm. The dialog must give the core's counts, show
// a plot that draws, follow its tolerances, take the window's current search as candidates, name the file at
// fault for bad input without throwing, and write what `synthtrack-cli recovery --out` writes plus a PNG.
// With ST_RECOVERY_SCREENSHOT set, the dialog is grabbed to that PNG for a look.
#include <gtest/gtest.h>

#include <QAction>
#include <QDir>
#include <QImage>
#include <QMenuBar>
#include <QTemporaryDir>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "main_window.hpp"
#include "observation.hpp"
#include "recovery_dialog.hpp"
#include "ui_test_support.hpp"

using namespace st;
using namespace st::ui;
namespace fs = std::filesystem;

namespace {

constexpr double kTRef = 60000.5;

void writeText(const fs::path& path, const std::string& text) {
  std::ofstream out(path);
  out << text;
  ASSERT_TRUE(out.good()) << path;
}

// Movers 1-4 on a row, expected SNR 5, 9, 14, 25, all at (0.5, -0.2) px/s.
nlohmann::json truthJson() {
  nlohmann::json objects = nlohmann::json::array();
  const double snr[] = {5.0, 9.0, 14.0, 25.0};
  for (int i = 0; i < 4; ++i)
    objects.push_back({{"id", i + 1},
                       {"x_px", 20.0 + 40.0 * i},
                       {"y_px", 30.0},
                       {"vx_px_s", 0.5},
                       {"vy_px_s", -0.2},
                       {"flux", 100.0},
                       {"expected_snr", snr[i]}});
  return {{"format", "synthtrack-injection-truth"}, {"t_ref_mjd", kTRef}, {"objects", objects}};
}

nlohmann::json candidate(double x, double y, double vx, double vy, double snr) {
  return {{"x", x},        {"y", y},     {"vx_px_s", vx},
          {"vy_px_s", vy}, {"snr", snr}, {"flags", nlohmann::json::array()}};
}

// Mover 1 missed; mover 2 found 1.5 px off; 3 and 4 found exactly; a false alarm far away.
nlohmann::json candidatesJson() {
  return {{"t_ref_mjd", kTRef},
          {"grid", {{"step_px_s", 0.1}, {"nvx", 11}, {"nvy", 11}}},
          {"candidates",
           {candidate(61.5, 30.0, 0.5, -0.2, 8.0), candidate(100.0, 30.0, 0.52, -0.2, 13.0),
            candidate(140.0, 30.0, 0.5, -0.18, 26.0), candidate(300.0, 300.0, 0.0, 0.0, 7.0)}}};
}

// Pixels of `image` that are clearly not white (the plot's ink).
int inkPixels(const QImage& image) {
  int n = 0;
  for (int y = 0; y < image.height(); ++y)
    for (int x = 0; x < image.width(); ++x)
      if (qGray(image.pixel(x, y)) < 128) ++n;
  return n;
}

class RecoveryDialogTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(tmp.isValid());
    dir = fs::path(tmp.path().toStdString());
    truthPath = dir / "truth.json";
    candPath = dir / "candidates.json";
    writeText(truthPath, truthJson().dump(2));
    writeText(candPath, candidatesJson().dump(2));
  }
  QString q(const fs::path& p) const { return QString::fromStdString(p.string()); }

  QTemporaryDir tmp;
  fs::path dir, truthPath, candPath;
  Observation obs;
};

TEST_F(RecoveryDialogTest, ScoresThreeOfFourWithAPlot) {
  RecoveryDialog d(&obs);
  EXPECT_FALSE(d.recompute()) << "nothing chosen yet";
  d.setTruthPath(q(truthPath));
  d.setCandidatesPath(q(candPath));
  ASSERT_TRUE(d.recompute()) << d.errorText().toStdString();
  EXPECT_TRUE(d.errorText().isEmpty());
  ASSERT_TRUE(d.result().has_value());
  EXPECT_EQ(d.result()->total, 4);
  EXPECT_EQ(d.result()->recovered, 3);
  EXPECT_FALSE(d.result()->objects[0].recovered()) << "mover 1 has no candidate";
  EXPECT_EQ(d.result()->unmatched.size(), 1u) << "the false alarm";
  EXPECT_TRUE(d.summaryText().contains("3 of 4 injected movers recovered")) << d.summaryText().toStdString();
  EXPECT_TRUE(d.svg().contains("3 of 4 movers recovered"));
  EXPECT_EQ(d.svg().count("<circle"), 4) << "one point per non-empty SNR bin (4-6, 8-10, 12-16, >=20)";
  const QImage plot = d.renderPlot(640);
  ASSERT_FALSE(plot.isNull());
  EXPECT_EQ(plot.width(), 640);
  EXPECT_EQ(plot.height(), 440);
  EXPECT_GT(inkPixels(plot), 2000) << "axes, labels and points are drawn";

  if (const char* shot = std::getenv("ST_RECOVERY_SCREENSHOT")) {
    d.show();
    test::waitFor([&] { return d.isVisible(); }, 2000);
    QApplication::processEvents();
    EXPECT_TRUE(d.grab().save(shot));
    plot.save(QString(shot).replace(".png", "_plot.png"));
  }
}

TEST_F(RecoveryDialogTest, TolerancesAreApplied) {
  RecoveryDialog d(&obs);
  d.setTruthPath(q(truthPath));
  d.setCandidatesPath(q(candPath));
  d.setTolerances(1.0, 1.0);
  ASSERT_TRUE(d.recompute()) << d.errorText().toStdString();
  EXPECT_EQ(d.result()->recovered, 2) << "mover 2's candidate is 1.5 px off";
  EXPECT_DOUBLE_EQ(d.result()->matchPx, 1.0);
  d.setTolerances(2.0, 0.1);
  ASSERT_TRUE(d.recompute());
  EXPECT_EQ(d.result()->recovered, 1) << "only mover 2's candidate has exactly the mover's velocity";
  EXPECT_NEAR(d.result()->matchVPxS, 0.01, 1e-12) << "0.1 grid steps of 0.1 px/s";
}

// recompute() refuses the input, and the error shown names `file`.
void expectRefusedNaming(RecoveryDialog& d, const fs::path& file) {
  EXPECT_FALSE(d.recompute());
  EXPECT_TRUE(d.errorText().contains(QString::fromStdString(file.string()))) << d.errorText().toStdString();
}

TEST_F(RecoveryDialogTest, BadInputNamesTheFile) {
  RecoveryDialog d(&obs);
  d.setTruthPath(q(truthPath));
  d.setCandidatesPath(q(candPath));
  ASSERT_TRUE(d.recompute());

  const fs::path broken = dir / "broken_candidates.json";
  writeText(broken, "{\"candidates\": [ {\"x\": 1,");
  d.setCandidatesPath(q(broken));
  expectRefusedNaming(d, broken);
  EXPECT_FALSE(d.result().has_value()) << "an old result is not shown beside an error";
  EXPECT_TRUE(d.svg().isEmpty());
  EXPECT_FALSE(d.saveTo(q(dir / "out")));
  EXPECT_TRUE(d.errorText().contains(q(broken))) << "a refused save keeps the reason in view";
  EXPECT_FALSE(fs::exists(dir / "out"));
  if (const char* shot = std::getenv("ST_RECOVERY_SCREENSHOT")) {
    d.show();
    QApplication::processEvents();
    d.grab().save(QString(shot).replace(".png", "_error.png"));
  }

  nlohmann::json t = truthJson();
  t["objects"][2].erase("x_px");
  const fs::path noKey = dir / "truth_without_x.json";
  writeText(noKey, t.dump());
  d.setTruthPath(q(noKey));
  d.setCandidatesPath(q(candPath));
  expectRefusedNaming(d, noKey);
  EXPECT_TRUE(d.errorText().contains("x_px")) << d.errorText().toStdString();

  const fs::path missing = dir / "no_such_truth.json";
  d.setTruthPath(q(missing));
  expectRefusedNaming(d, missing);

  // Candidates without a grid step: the velocity tolerance in grid steps cannot be set.
  nlohmann::json c = candidatesJson();
  c.erase("grid");
  const fs::path noGrid = dir / "candidates_without_grid.json";
  writeText(noGrid, c.dump());
  d.setTruthPath(q(truthPath));
  d.setCandidatesPath(q(noGrid));
  expectRefusedNaming(d, noGrid);
}

TEST_F(RecoveryDialogTest, SaveWritesWhatTheCliWritesAndAPng) {
  RecoveryDialog d(&obs);
  d.setTruthPath(q(truthPath));
  d.setCandidatesPath(q(candPath));
  ASSERT_TRUE(d.recompute());
  const fs::path out = dir / "recovery";
  ASSERT_TRUE(d.saveTo(q(out))) << d.errorText().toStdString();
  for (const char* name : {"recovery.json", "completeness.csv", "objects.csv", "unmatched.csv",
                           "completeness.svg", "completeness.png"})
    EXPECT_TRUE(fs::is_regular_file(out / name) && fs::file_size(out / name) > 0) << name;
  std::ifstream in(out / "recovery.json");
  const nlohmann::json j = nlohmann::json::parse(in);
  EXPECT_EQ(j.at("summary").at("injected").get<int>(), 4) << j.at("summary").dump();
  EXPECT_EQ(j.at("summary").at("recovered").get<int>(), 3);
  ASSERT_EQ(j.at("sets").size(), 1u);
  EXPECT_EQ(j["sets"][0]["truth_file"], truthPath.string());
  EXPECT_EQ(j["sets"][0]["candidates_file"], candPath.string());
  EXPECT_EQ(j["sets"][0]["candidates"], 4);
  const QImage png(q(out / "completeness.png"));
  ASSERT_FALSE(png.isNull());
  EXPECT_EQ(png.width(), 1280);
  EXPECT_GT(inkPixels(png), 4000);
  std::ifstream svg(out / "completeness.svg");
  const std::string svgText((std::istreambuf_iterator<char>(svg)), std::istreambuf_iterator<char>());
  EXPECT_EQ(QString::fromStdString(svgText), d.svg());

  // A folder that cannot be made (a file is in the way): an error naming it, no crash.
  writeText(dir / "blocker", "x");
  EXPECT_FALSE(d.saveTo(q(dir / "blocker" / "sub")));
  EXPECT_FALSE(d.errorText().isEmpty());
  EXPECT_TRUE(d.errorText().contains("blocker")) << d.errorText().toStdString();
}

TEST_F(RecoveryDialogTest, CurrentSearchIsScoredLikeItsJson) {
  RecoveryDialog d(&obs);
  EXPECT_FALSE(d.currentSearchAvailable());
  EXPECT_FALSE(d.setCandidateSource(RecoveryDialog::CandidateSource::CurrentSearch));

  auto result = std::make_shared<search::SearchResult>();
  result->tRefMjd = kTRef;
  result->grid.stepPxS = 0.1;
  result->grid.nvx = result->grid.nvy = 11;
  auto add = [&](int x, int y, double snr) {
    search::Candidate c;
    c.x = x;
    c.y = y;
    c.v = {0.5, -0.2};
    c.snr = snr;
    result->candidates.push_back(c);
  };
  add(61, 30, 8.0);    // mover 2, 1 px off
  add(100, 30, 13.0);  // mover 3
  add(140, 31, 26.0);  // mover 4, 1 px off
  obs.setResult(result);
  EXPECT_TRUE(d.currentSearchAvailable());
  d.setTruthPath(q(truthPath));
  ASSERT_TRUE(d.setCandidateSource(RecoveryDialog::CandidateSource::CurrentSearch));
  ASSERT_TRUE(d.recompute()) << d.errorText().toStdString();
  EXPECT_EQ(d.result()->recovered, 3);
  EXPECT_EQ(d.result()->total, 4);
  EXPECT_TRUE(d.result()->unmatched.empty());

  obs.setResult(nullptr);
  EXPECT_EQ(d.candidateSource(), RecoveryDialog::CandidateSource::File) << "falls back when the search goes";
}

TEST(RecoveryDialogMenu, RunMenuOpensTheDialog) {
  MainWindow w(test::fakeServices(test::movingDotCube(32, 32, 8, {1.0, 0.0}, 10, 10)));
  QAction* action = nullptr;
  for (QAction* menu : w.menuBar()->actions())
    if (menu->menu() && menu->text() == "&Run")
      for (QAction* a : menu->menu()->actions())
        if (a->text().startsWith("&Injection recovery")) action = a;
  ASSERT_NE(action, nullptr);
  action->trigger();
  ASSERT_NE(w.recoveryDialog(), nullptr);
  EXPECT_TRUE(w.recoveryDialog()->isVisible());
  EXPECT_FALSE(w.recoveryDialog()->currentSearchAvailable()) << "no search has run";
}

}  // namespace

ST_UI_TEST_MAIN_ISOLATED()

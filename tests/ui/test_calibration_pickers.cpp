// The Calibration stage's bias/flat/dark pickers (issue 15 item 4): folders beside the science folder are
// offered with a note the user can clear; the lists go into the stages the pre-processing job gets and into
// the session file (older sessions, without them, still open with none).
#include <gtest/gtest.h>

#include <QDir>
#include <QFile>
#include <QLabel>
#include <QLineEdit>
#include <QPushButton>

#include "calibration_files.hpp"
#include "processing_panel.hpp"
#include "session_snapshot.hpp"
#include "test_support.hpp"
#include "ui_test_support.hpp"

using namespace st;
using namespace st::ui;

namespace {

std::vector<StageSpec> stagesWithCalibration() {
  return {{"Calibration (overscan, trim, bad pixels)",
           true,
           true,
           {},
           {StageFiles{"bias", "Bias frames", {}, ""}, StageFiles{"flat", "Flat frames", {}, ""},
            StageFiles{"dark", "Dark frames", {}, ""}}},
          {"Matched filter", true, false, {StageParam{"fwhm", "FWHM", "px", 2.5, 0.5, 20, 2, ""}}}};
}

void touch(const QString& path) {
  QFile f(path);
  ASSERT_TRUE(f.open(QIODevice::WriteOnly));
  f.write("x");
}

/// night/science (2 frames), night/Bias (1 file), night/FLATS (1 file), night/dark (empty), night/notes.
QString makeNight(const std::filesystem::path& root) {
  const QString night = QString::fromStdString((root / "night").string());
  for (const char* d : {"science", "Bias", "FLATS", "dark", "notes"})
    QDir().mkpath(night + "/" + d);
  touch(night + "/science/a.fits");
  touch(night + "/science/b.fits");
  touch(night + "/Bias/z1.fits");
  touch(night + "/FLATS/f1.fits");
  touch(night + "/notes/readme.txt");
  return night;
}

}  // namespace

TEST(CalibrationPickers, SiblingFoldersAreOfferedCaseInsensitively) {
  test::TempDir tmp;
  const QString night = makeNight(tmp.path());
  const CalibrationOffer offer = offerCalibrationFolders({night + "/science"});
  ASSERT_EQ(offer.folders.size(), 2u);  // dark/ is empty: not offered
  EXPECT_EQ(offer.folders.at(kBiasFiles), QStringList{QDir(night + "/Bias").absolutePath()});
  EXPECT_EQ(offer.folders.at(kFlatFiles), QStringList{QDir(night + "/FLATS").absolutePath()});
  EXPECT_TRUE(offer.note.contains("Bias/ and FLATS/")) << offer.note.toStdString();
  EXPECT_TRUE(offer.note.contains("science/")) << offer.note.toStdString();
  // Files that all sit in science/ are the same observation; files from two folders offer nothing.
  EXPECT_EQ(offerCalibrationFolders({night + "/science/a.fits", night + "/science/b.fits"}).folders.size(), 2u);
  EXPECT_TRUE(offerCalibrationFolders({night + "/science/a.fits", night + "/Bias/z1.fits"}).folders.empty());
  EXPECT_TRUE(offerCalibrationFolders({night + "/notes"}).folders.size() == 2u);  // any sibling folder
  EXPECT_TRUE(offerCalibrationFolders({night + "/missing"}).folders.empty());
}

TEST(CalibrationPickers, PanelShowsTheOfferUntilCleared) {
  test::TempDir tmp;
  const QString night = makeNight(tmp.path());
  ProcessingPanel panel(stagesWithCalibration());
  panel.resize(360, 500);
  panel.show();
  const CalibrationOffer offer = offerCalibrationFolders({night + "/science"});
  panel.offerFiles(offer.folders, offer.note);
  EXPECT_EQ(panel.offerNote(), offer.note);
  EXPECT_EQ(panel.files("bias"), offer.folders.at(kBiasFiles));
  const auto stages = panel.stages();
  EXPECT_EQ(stageFiles(stages, "bias"), std::vector<std::string>{offer.folders.at(kBiasFiles)[0].toStdString()});
  EXPECT_TRUE(stageFiles(stages, "dark").empty());
  auto* note = panel.findChild<QLabel*>("calibrationOfferNote");
  ASSERT_NE(note, nullptr);
  EXPECT_TRUE(note->isVisible());

  // The user sets the flat by hand: the offer still covers the bias.
  panel.setFiles("flat", {"/x/f1.fits", "/x/f2.fits"});
  EXPECT_EQ(panel.files("flat"), (QStringList{"/x/f1.fits", "/x/f2.fits"}));
  EXPECT_FALSE(panel.offerNote().isEmpty());
  // Clear: the offered bias goes, the hand-set flat stays, the note goes.
  auto* clear = panel.findChild<QPushButton*>("clearCalibrationOffer");
  ASSERT_NE(clear, nullptr);
  clear->click();
  EXPECT_TRUE(panel.files("bias").isEmpty());
  EXPECT_EQ(panel.files("flat").size(), 2);
  EXPECT_TRUE(panel.offerNote().isEmpty());
  EXPECT_FALSE(note->isVisible());
  // Typed paths ("; " between) are read back as a list; Defaults keeps them.
  auto* dark = panel.findChild<QLineEdit*>("dark");
  ASSERT_NE(dark, nullptr);
  dark->setText(" /d/one.fits ;/d/two ; ");
  panel.resetDefaults();
  EXPECT_EQ(panel.files("dark"), (QStringList{"/d/one.fits", "/d/two"}));
  panel.clearFiles();
  EXPECT_TRUE(panel.files("flat").isEmpty());
}

TEST(CalibrationPickers, ListsAreSavedInTheSessionAndOldSessionsOpen) {
  Observation obs;
  SessionParameters params;
  params.stages = stagesWithCalibration();
  params.stages[0].files[0].paths = {"/night/bias"};
  params.stages[0].files[1].paths = {"/night/flat/a.fits", "/night/flat/b.fits"};
  const session::Session s = makeSession(obs, {"/night/science"}, params);
  const auto text = session::toJson(s).dump();
  const session::Session back = session::fromJson(nlohmann::json::parse(text), "s.json");
  const SessionSnapshot snap = restoreSnapshot(back, stagesWithCalibration(), "s.json");
  EXPECT_EQ(stageFiles(snap.parameters.stages, "bias"), std::vector<std::string>{"/night/bias"});
  EXPECT_EQ(stageFiles(snap.parameters.stages, "flat").size(), 2u);
  EXPECT_TRUE(stageFiles(snap.parameters.stages, "dark").empty());

  // A session written before the pickers: no "files" key; it opens, with no calibration frames.
  nlohmann::json old = nlohmann::json::parse(text);
  for (auto& [name, stage] : old["parameters"]["preprocess"].items())
    stage.erase("files");
  const SessionSnapshot oldSnap =
      restoreSnapshot(session::fromJson(old, "old.json"), stagesWithCalibration(), "old.json");
  EXPECT_TRUE(stageFiles(oldSnap.parameters.stages, "bias").empty());
  // A mistyped list names the file.
  nlohmann::json bad = nlohmann::json::parse(text);
  bad["parameters"]["preprocess"]["Calibration (overscan, trim, bad pixels)"]["files"]["bias"] = 3;
  EXPECT_THROW((void)restoreSnapshot(session::fromJson(bad, "bad.json"), stagesWithCalibration(), "bad.json"),
               InputError);
}

ST_UI_TEST_MAIN()

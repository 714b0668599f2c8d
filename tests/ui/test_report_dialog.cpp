// The Reports dialog on the main window, offscreen, on a moving-dot cube with a TAN WCS (1"/px, north up,
// east left): only candidates labelled real reach ADES and MPC; the low-SNR one shows a visible warning;
// JSON/CSV carry every candidate with its label; DS9 regions are in the WCS frame; the FITS stacks carry a
// WCS and provenance and the object-tracked one has all frames of the dot on the candidate's pixel; the
// settings persist; errors name the path; a submission missing what ADES requires is said in the dialog and
// refused before any file is written. With ST_REPORT_OUT set, the outputs stay there for the DS9 and
// astropy checks of tests/python/test_gui_reports.py.
#include <gtest/gtest.h>

#include <QFile>
#include <QSettings>
#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "job_runner.hpp"
#include "main_window.hpp"
#include "report_dialog.hpp"
#include "search_panel.hpp"
#include "session_controller.hpp"
#include "st/io/fits_reader.hpp"
#include "st/io/wcs.hpp"
#include "test_support.hpp"
#include "ui_test_support.hpp"

using namespace st;
using namespace st::ui;

namespace {

constexpr Velocity kDotV{8.0, -4.0};

FrameCube cubeWithWcs() {
  FrameCube cube = test::movingDotCube(96, 96, 40, kDotV, 40, 50);
  FitsHeader& h = cube.header;
  test::setTanWcs(h, 150.0, 30.0, 48.5, 48.5, 1.0);
  h.setString("RADESYS", "ICRS");
  h.setNumber("EQUINOX", 2000.0);
  cube.wcs = Wcs::fromHeader(h, nullptr);
  cube.plateScaleArcsecPerPx = 1.0;
  return cube;
}

std::vector<std::string> readLines(const std::string& path) {
  std::ifstream in(path);
  std::vector<std::string> lines;
  for (std::string l; std::getline(in, l);)
    lines.push_back(l);
  return lines;
}

std::string readAll(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// A converged fit at the candidate's cell with its sky position through the cube's WCS, and `segments`
// segment positions on the sky at SNR 8 (fitCandidate's segment check).
candidate::FitSummary fitAt(const search::Candidate& c, const FrameCube& raw, double snr, int segments = 0) {
  const auto sky = raw.wcs->pixelToSky(c.x, c.y);
  candidate::FitSummary f;
  f.status = fit::FitStatus::Converged;
  f.x = c.x;
  f.y = c.y;
  f.v = c.v;
  f.snr = snr;
  f.sky = candidate::SkyPosition{sky.raDeg, sky.decDeg};
  f.tRefMjd = raw.tRefMjd();
  f.sigmaRaArcsec = 0.1;
  f.sigmaDecArcsec = 0.1;
  if (segments > 0) f.segments = candidate::SegmentSummary{};
  if (segments > 0) f.segments->positionSegments = segments;
  for (int k = 0; k < segments; ++k) {
    const double t = -10.0 + 20.0 * k / std::max(1, segments - 1);
    const auto at = raw.wcs->pixelToSky(c.x + c.v.vx * t, c.y + c.v.vy * t);
    f.segments->positions.push_back({k + 1, raw.tRefMjd() + t / 86400.0, t, c.x + c.v.vx * t,
                                     c.y + c.v.vy * t, 0.2, 0.2, 8.0, at.raDeg, at.decDeg, 0.15, 0.15});
  }
  return f;
}

class ReportDialogTest : public ::testing::Test {
 protected:
  void SetUp() override {
    w = std::make_unique<MainWindow>(test::fakeServices(cubeWithWcs()));
    w->resize(1200, 800);
    w->show();
    w->openDemo();
    ASSERT_TRUE(test::waitFor([&] { return w->observation()->prepared() && !w->jobs()->busy(); }));
    w->searchPanel()->setGridPxS({6.0, -3.0}, 3.0, 0.5);
    w->runSearch();
    ASSERT_TRUE(test::waitFor([&] { return w->observation()->result() && !w->jobs()->busy(); }));
    ASSERT_GE(w->observation()->result()->candidates.size(), 3u);
  }
  std::unique_ptr<MainWindow> w;
};

}  // namespace

TEST_F(ReportDialogTest, OnlyRealCandidatesReachAdesAndMpcAndLowSnrIsWarned) {
  Observation* obs = w->observation();
  const auto& cands = obs->result()->candidates;
  const FrameCube& raw = *obs->raw();
  obs->setCandidateFit(0, fitAt(cands[0], raw, 14.0, 4));  // a tracklet of 4 segment positions
  obs->setCandidateFit(1, fitAt(cands[1], raw, 5.0));  // below the safe SNR 7
  obs->setCandidateFit(2, fitAt(cands[2], raw, 20.0));
  obs->setCandidateLabel(0, session::Label::Real);
  obs->setCandidateLabel(1, session::Label::Real);
  obs->setCandidateLabel(2, session::Label::Artifact, session::ArtifactReason::Ghost);
  obs->setSelected(0);

  ReportDialog* d = w->reportDialog();
  report::SubmissionSettings s;
  s.stationCode = "291";
  s.observers = "A. Observer";
  s.astCat = "Gaia3";
  s.mpcCatalogCode = 'W';
  s.apertureM = 0.5;  // ADES requires the telescope aperture
  d->setSubmissionSettings(s);
  d->show();
  d->refreshWarnings();
  EXPECT_TRUE(d->warningVisible());
  EXPECT_TRUE(d->warningText().contains("st00002: SNR 5.00")) << d->warningText().toStdString();
  EXPECT_FALSE(d->warningText().contains("st00001"));
  // Candidate 2 has no segment positions: its one whole-fit position, said.
  EXPECT_TRUE(d->warningText().contains("candidate 2 has 0 segment position(s) on the sky"))
      << d->warningText().toStdString();
  EXPECT_EQ(d->submissionSettings().positions, report::TrackletPositions::Segments);

  test::TempDir tmp;
  const char* keep = std::getenv("ST_REPORT_OUT");
  const std::string folder = keep && *keep ? std::string(keep) : (tmp / "out").string();
  d->setOutput(QString::fromStdString(folder), "run");
  d->setOutputs(true, true, true, true, true, true);
  d->setStackChoice(StackChoice::Real);
  bool done = false, ok = false;
  QObject::connect(d, &ReportDialog::exportFinished, [&](bool good, const QString&) {
    done = true;
    ok = good;
  });
  ASSERT_TRUE(d->exportReports());
  ASSERT_TRUE(test::waitFor([&] { return done; }));
  ASSERT_TRUE(ok) << d->resultText().toStdString();
  EXPECT_TRUE(d->resultText().contains("st00002: SNR 5.00 is below the safe 7.0"));

  // ADES: header blocks, the field-name line, then the two real candidates: the first's tracklet of four
  // segment positions, the second's one position.
  std::vector<std::string> data;
  for (const auto& l : readLines(folder + "/run.psv"))
    if (!l.empty() && l[0] != '#' && l[0] != '!' && l.find("trkSub") == std::string::npos) data.push_back(l);
  ASSERT_EQ(data.size(), 5u);
  for (int k = 0; k < 4; ++k)
    EXPECT_EQ(data[k].rfind("st00001", 0), 0u) << data[k];
  EXPECT_EQ(data[4].rfind("st00002", 0), 0u) << data[4];
  EXPECT_NE(readAll(folder + "/run.psv").find("! mpcCode 291"), std::string::npos);
  // MPC 80-column: header lines (COD, OBS, ...) then the five observations, 80 columns, station in 78-80,
  // the tracklet's four at increasing times.
  std::vector<std::string> obsLines;
  for (const auto& l : readLines(folder + "/run_mpc.txt"))
    if (l.size() == 80 && l.substr(77, 3) == "291" && l.substr(0, 4) != "COD ") obsLines.push_back(l);
  ASSERT_EQ(obsLines.size(), 5u);
  for (int k = 0; k < 4; ++k) {
    EXPECT_EQ(obsLines[k].substr(5, 7), "st00001");
    if (k > 0) {
      EXPECT_GT(obsLines[k].substr(15, 17), obsLines[k - 1].substr(15, 17));
    }
  }
  EXPECT_EQ(obsLines[4].substr(5, 7), "st00002");
  EXPECT_EQ(readAll(folder + "/run_mpc.txt").find("st00003"), std::string::npos);

  // JSON and CSV: every candidate, with its label.
  const auto json = nlohmann::json::parse(readAll(folder + "/run_candidates.json"));
  ASSERT_EQ(json["candidates"].size(), cands.size());
  EXPECT_EQ(json["candidates"][2]["label"], "artifact");
  EXPECT_EQ(json["candidates"][2]["reason"], "ghost");
  EXPECT_EQ(session::fromSearchJson(json).candidates[0].fit, obs->candidateState(0)->fit);
  const auto csv = readLines(folder + "/run_candidates.csv");
  ASSERT_EQ(csv.size(), cands.size() + 1);
  EXPECT_EQ(csv[1].substr(0, 7), "1,real,");
  // DS9: in the WCS's own frame (RADESYS ICRS here: icrs), one circle per candidate.
  const std::string reg = readAll(folder + "/run.reg");
  EXPECT_NE(reg.find("\nicrs\n"), std::string::npos);
  std::size_t circles = 0;
  for (auto p = reg.find("circle("); p != std::string::npos; p = reg.find("circle(", p + 1))
    ++circles;
  EXPECT_EQ(circles, cands.size());

  // FITS stacks of the two real candidates, tracking the sky and the object.
  // (A stack has one epoch, TREFMJD, and no DATE-OBS: the reader is given a time.)
  io::LoadOptions opts;
  opts.startMjd = 60000.0;
  opts.frameRateHz = 1.0;
  NullProgress progress;
  CancelToken cancel;
  const FrameCube object = io::loadFrames({folder + "/run_c001_object.fits"}, opts, progress, cancel);
  const FrameCube sky = io::loadFrames({folder + "/run_c001_sky.fits"}, opts, progress, cancel);
  ASSERT_TRUE(object.wcs);
  EXPECT_EQ(object.header.getString("STMODE").value_or(""), "IPSA");
  EXPECT_NEAR(object.header.getDouble("STVX").value_or(0), cands[0].v.vx, 1e-9);
  EXPECT_NEAR(sky.header.getDouble("STVX").value_or(1), 0.0, 1e-12);
  // Coverage-normalised and background-subtracted (issue 18 §6): the dot of 1 count in each of the 40 frames
  // is 1 count per frame on a background of 0 (it was the raw sum, 40, before).
  EXPECT_FLOAT_EQ(object.frame(0)[static_cast<std::size_t>(cands[0].y) * 96 + cands[0].x], 1.0f);
  EXPECT_EQ(object.header.getString("BUNIT").value_or(""), "adu");
  EXPECT_TRUE(QFile::exists(QString::fromStdString(folder + "/run_c002_object.fits")));
  EXPECT_FALSE(QFile::exists(QString::fromStdString(folder + "/run_c003_object.fits")));
  // The stack's WCS at t_ref maps the candidate's pixel where the cube's does (sky rate 0 here).
  const auto a = object.wcs->pixelToSky(cands[0].x, cands[0].y),
             b = raw.wcs->pixelToSky(cands[0].x, cands[0].y);
  EXPECT_NEAR(a.raDeg, b.raDeg, 1e-9);
  EXPECT_NEAR(a.decDeg, b.decDeg, 1e-9);

  // The settings went into the session (autosaved with it) and persist for the next dialog.
  EXPECT_EQ(w->session()->settings().value("station", ""), "291");
  EXPECT_EQ(w->session()->settings().value("ast_cat", ""), "Gaia3");
  ReportDialog again({obs, {}});
  EXPECT_EQ(again.submissionSettings().stationCode, "291");
  EXPECT_EQ(again.submissionSettings().mpcCatalogCode, 'W');
}

TEST_F(ReportDialogTest, ErrorsNameThePath) {
  ReportDialog* d = w->reportDialog();
  d->setOutput("/proc/st-cannot-create", "x");
  d->setOutputs(true, false, false, false, false, false);
  bool done = false, ok = true;
  QObject::connect(d, &ReportDialog::exportFinished, [&](bool good, const QString&) {
    done = true;
    ok = good;
  });
  ASSERT_TRUE(d->exportReports());
  ASSERT_TRUE(test::waitFor([&] { return done; }));
  EXPECT_FALSE(ok);
  EXPECT_TRUE(d->resultText().contains("/proc/st-cannot-create")) << d->resultText().toStdString();
  // No real candidate: nothing to warn about.
  d->refreshWarnings();
  EXPECT_FALSE(d->warningVisible());
}

TEST_F(ReportDialogTest, AnInvalidSubmissionIsSaidAndRefusedBeforeWriting) {
  ReportDialog* d = w->reportDialog();
  report::SubmissionSettings s;  // station and observer, but no aperture and no catalogue
  s.stationCode = "291";
  s.observers = "A. Observer";
  d->setSubmissionSettings(s);
  test::TempDir tmp;
  d->setOutput(QString::fromStdString((tmp / "out").string()), "run");
  d->setOutputs(true, false, false, false, true, false);
  d->show();
  d->refreshWarnings();
  EXPECT_TRUE(d->warningVisible());
  EXPECT_TRUE(d->warningText().contains("ADES needs")) << d->warningText().toStdString();
  EXPECT_TRUE(d->warningText().contains("aperture"));
  EXPECT_TRUE(d->warningText().contains("astCat"));
  bool done = false, ok = true;
  QObject::connect(d, &ReportDialog::exportFinished, [&](bool good, const QString&) {
    done = true;
    ok = good;
  });
  ASSERT_TRUE(d->exportReports());
  ASSERT_TRUE(test::waitFor([&] { return done; }));
  EXPECT_FALSE(ok);
  EXPECT_TRUE(d->resultText().contains("aperture")) << d->resultText().toStdString();
  EXPECT_FALSE(QFile::exists(QString::fromStdString((tmp / "out" / "run.psv").string())));
  EXPECT_FALSE(QFile::exists(QString::fromStdString((tmp / "out" / "run_candidates.json").string())));
  // Given them, the warning goes.
  s.apertureM = 0.5;
  s.astCat = "Gaia3";
  d->setSubmissionSettings(s);
  d->refreshWarnings();
  EXPECT_FALSE(d->warningText().contains("ADES needs")) << d->warningText().toStdString();
}

ST_UI_TEST_MAIN()

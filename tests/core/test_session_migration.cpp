// A session file written by main on 2026-11-25 (format 1, tests/data/README.md) opens into the typed
// candidate record with every value the file held, is saved as format 2, and reads back identical; the report
// bundle of the migrated session equals the one main wrote from the same file (ADES PSV and MPC 80-column,
// byte for byte, as `synthtrack-cli report --session` wrote them at 6abd10c).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "st/common/error.hpp"
#include "st/report/report_bundle.hpp"
#include "st/report/submission_settings.hpp"
#include "st/session/session.hpp"
#include "test_support.hpp"

namespace st::session {
namespace {

namespace fs = std::filesystem;

const fs::path kData = fs::path(ST_SOURCE_DIR) / "tests" / "data";

std::string readAll(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

/// A copy of the committed file in a temporary folder (loading never writes, but a failed load copies it
/// aside beside itself).
fs::path copyOfV1(const test::TempDir& dir) {
  const fs::path to = dir / "v1.synthtrack-session.json";
  fs::copy_file(kData / "session_v1_main_20261125.json", to);
  return to;
}

TEST(SessionMigration, FormatOneFromMainLoadsTyped) {
  test::TempDir dir;
  const fs::path path = copyOfV1(dir);
  const nlohmann::json raw = nlohmann::json::parse(readAll(path));
  ASSERT_EQ(raw["version"], 1);
  const Session s = SessionStore(path.string()).load();
  EXPECT_EQ(s.version, 1);
  EXPECT_EQ(s.changes, 14);
  ASSERT_EQ(s.candidates.size(), 2u);
  // Candidate 1: real, with the accepted fit, its segment check and sky position.
  const CandidateState& c = s.candidates[0];
  const nlohmann::json& rc = raw["candidates"][0];
  EXPECT_EQ(c.label, Label::Real);
  EXPECT_EQ(c.note, "fast mover, \"confirm\"");
  EXPECT_EQ(c.search.cell.x, rc["candidate"]["x"].get<int>());
  EXPECT_EQ(c.search.cell.v.vx, rc["candidate"]["vx_px_s"].get<double>());
  EXPECT_EQ(c.search.cell.snr, rc["candidate"]["snr"].get<double>());
  EXPECT_EQ(c.search.cell.fap, rc["candidate"]["fap"].get<double>());
  EXPECT_EQ(c.search.cell.nIn, rc["candidate"]["n_frames"].get<int>());
  ASSERT_TRUE(c.search.rateDegPerDay.has_value());
  EXPECT_EQ(*c.search.rateDegPerDay, rc["candidate"]["rate_deg_day"].get<double>());
  ASSERT_TRUE(c.fitted());
  const nlohmann::json& rf = rc["fit"];
  EXPECT_EQ(c.fit->x, rf["x"].get<double>());
  EXPECT_EQ(c.fit->v.vy, rf["vy_px_s"].get<double>());
  EXPECT_EQ(c.fit->sigma.xPx, rf["sigma_x_px"].get<double>());
  EXPECT_EQ(c.fit->sigma.velPaperPxS, rf["sigma_vel_paper_px_s"].get<double>());
  EXPECT_EQ(c.fit->snr, rf["snr"].get<double>());
  EXPECT_EQ(c.fit->iterations, rf["iterations"].get<int>());
  ASSERT_TRUE(c.fit->segments.has_value());
  EXPECT_EQ(c.fit->segments->snr, rf["segment_snr"].get<std::vector<double>>());
  EXPECT_EQ(c.fit->segments->flagged, rf["segments_flagged"].get<bool>());
  ASSERT_TRUE(c.sky());
  EXPECT_EQ(c.sky()->raDeg, rf["ra_deg"].get<double>());
  EXPECT_EQ(c.sky()->decDeg, rf["dec_deg"].get<double>());
  EXPECT_EQ(c.sky()->paDeg, rf["pa_deg"].get<double>());
  ASSERT_EQ(c.artifacts.size(), rc["artifacts"].size());
  ASSERT_FALSE(c.artifacts.empty());
  EXPECT_EQ(c.artifacts[0].kind, vet::ArtifactKind::ChargeLeakage);
  EXPECT_EQ(c.artifacts[0].evidence, rc["artifacts"][0]["evidence"].get<std::string>());
  // Candidate 2: an artifact (ghost) without a fit.
  EXPECT_EQ(s.candidates[1].label, Label::Artifact);
  EXPECT_EQ(s.candidates[1].reason, ArtifactReason::Ghost);
  EXPECT_FALSE(s.candidates[1].fit.has_value());
  // What stays JSON is kept as it was.
  EXPECT_EQ(s.search, raw["search"]);
  EXPECT_EQ(s.parameters, raw["parameters"]);
  EXPECT_EQ(s.settings, raw["settings"]);
}

TEST(SessionMigration, SavedAsFormatTwoAndReadBackIdentical) {
  test::TempDir dir;
  const fs::path path = copyOfV1(dir);
  SessionStore store(path.string());
  Session s = store.load();
  store.save(s);
  const nlohmann::json saved = nlohmann::json::parse(readAll(path));
  EXPECT_EQ(saved["version"], kSessionFormatVersion);
  EXPECT_TRUE(saved["candidates"][0].contains("search"));
  EXPECT_TRUE(saved["candidates"][0]["fit"]["sky"].contains("ra_deg"));
  Session back = store.load();
  EXPECT_EQ(back.version, kSessionFormatVersion);
  back.version = s.version;
  EXPECT_EQ(back, s);
}

// The 80-column reference differs from what main wrote on 2026-11-25 in column 72, blank since 2026-12-04
// (the MPC fills the catalogue code: "On new submissions, column 72 must be blank"), and in the NET line,
// which names the catalogue as the MPC does (Gaia-DR2 for astCat Gaia2).
TEST(SessionMigration, SubmissionFilesEqualWhatMainWrote) {
  test::TempDir dir;
  const Session s = SessionStore(copyOfV1(dir).string()).load();
  report::ReportRequest r;
  r.session = s;
  r.submission = report::submissionFromJson(s.settings);
  r.files[report::ReportFile::AdesPsv] = (dir / "out.psv").string();
  r.files[report::ReportFile::Mpc80] = (dir / "out_mpc.txt").string();
  NullProgress progress;
  CancelToken cancel;
  const report::ReportOutcome out = report::writeReports(r, progress, cancel);
  EXPECT_EQ(out.detections, 1u);
  EXPECT_EQ(readAll(dir / "out.psv"), readAll(kData / "session_v1_main_20261125.psv"));
  EXPECT_EQ(readAll(dir / "out_mpc.txt"), readAll(kData / "session_v1_main_20261125_mpc.txt"));
}

TEST(SessionMigration, BrokenCandidateNamesTheFileCandidateAndKey) {
  nlohmann::json j = nlohmann::json::parse(readAll(kData / "session_v1_main_20261125.json"));
  j["candidates"][1]["candidate"]["snr"] = "high";
  try {
    (void)fromJson(j, "/tmp/x.json");
    FAIL() << "accepted a candidate whose snr is text";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("/tmp/x.json"), std::string::npos) << what;
    EXPECT_NE(what.find("candidate 2"), std::string::npos) << what;
    EXPECT_NE(what.find("'snr'"), std::string::npos) << what;
  }
}

}  // namespace
}  // namespace st::session

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>

#include "st/common/units.hpp"
#include "st/report/search_report.hpp"
#include "test_support.hpp"

namespace st::report {
namespace {

search::FilteredCube scanCube() {
  search::FilteredCube fc;
  fc.frames = FrameCube(64, 64, 10);
  for (std::size_t n = 0; n < 10; ++n)
    fc.frames.info()[n].mjdMid = 60000.0 + n * 0.06 / kSecondsPerDay;
  fc.frames.plateScaleArcsecPerPx = 0.305;
  fc.skyRate = {16.39, 0.0};  // a scanning telescope: the stars cross the frames at 5"/s
  fc.sigmaF = 2.0;
  fc.psfFwhmPx = 3.0;
  return fc;
}

search::SearchResult twoCandidates() {
  search::SearchResult r;
  r.grid = {{16.39, 0.0}, 0.1, 21, 21};
  search::Candidate moving;
  moving.x = 30;
  moving.y = 20;
  moving.v = {16.39 - 0.8, 0.0};  // 0.8 px/s relative to the stars
  moving.snr = 15.0;
  moving.nIn = 10;
  search::Candidate star = moving;
  star.v = {16.41, 0.05};  // within one step of the sky rate
  star.nIn = 7;
  r.candidates = {moving, star};
  r.trials = {64, 64, 21, 21};
  r.method = st::search::SearchMethod::Tree;
  r.methodReason = "auto: tree, clearly faster (estimated exact 9 s, tree 1 s; \"9x\")";
  return r;
}

TEST(SearchReport, RatesAreOnTheSkyRelativeToTheStarsAndFlagsStatics) {
  const auto fc = scanCube();
  const nlohmann::json j = searchResultToJson(fc, twoCandidates(), {"obs.fits"});
  ASSERT_EQ(j["candidates"].size(), 2u);
  const auto& a = j["candidates"][0];
  // |v - skyRate| = 0.8 px/s at 0.305"/px = 0.8 * 0.305 * 86400 / 3600 deg/day, not the scan's ~120 deg/day.
  EXPECT_NEAR(a["rate_deg_day"].get<double>(), pxPerSecToDegPerDay(0.8, 0.305), 1e-9);
  EXPECT_TRUE(a["flags"].empty());
  EXPECT_EQ(a["x"], 30);
  EXPECT_EQ(a["n_frames"], 10);
  const auto& s = j["candidates"][1];
  EXPECT_EQ(s["flags"], nlohmann::json({"at_sky_rate", "partial"}));
  EXPECT_EQ(j["trials"]["total"].get<double>(), 64.0 * 64 * 21 * 21);
  EXPECT_NEAR(j["sky_rate"]["vx_px_s"].get<double>(), 16.39, 1e-12);
  EXPECT_EQ(j["method"], "tree");
  EXPECT_EQ(j["method_reason"], twoCandidates().methodReason);
}

// "crosses_brighter": a cell whose track meets (within 2 FWHM over the span) the track of a candidate at
// least 10 times brighter at another velocity; not for a cell that never meets it, one less than 10 times
// fainter, or one at the bright one's own velocity.
TEST(SearchReport, CellsCrossingAMuchBrighterTrackAreFlagged) {
  search::FilteredCube fc = scanCube();
  fc.frames = FrameCube(128, 128, 41);
  for (std::size_t n = 0; n < 41; ++n)  // -20 to +20 s about t_ref
    fc.frames.info()[n].mjdMid = 60000.0 + static_cast<double>(n) / kSecondsPerDay;
  search::SearchResult r = twoCandidates();
  search::Candidate bright;
  bright.x = 50;
  bright.y = 50;
  bright.v = {16.39, 0.5};
  bright.snr = 4000.0;
  bright.nIn = 41;
  search::Candidate crossing = bright;  // 10 px to the right, 1 px/s slower in x: meets it at t = +10 s
  crossing.x = 60;
  crossing.v = {15.39, 0.5};
  crossing.snr = 200.0;
  search::Candidate away = crossing;  // 30 px above: never within 2 FWHM
  away.y = 80;
  search::Candidate bright2 = crossing;  // crossing, but only 8 times fainter
  bright2.snr = 500.0;
  search::Candidate same = bright;  // the bright one's own motion (a cell of its cluster)
  same.x = 53;
  same.snr = 150.0;
  search::Candidate later = crossing;  // 30 px to the right: the tracks would meet at t = +30 s, after the span
  later.x = 80;
  r.candidates = {bright, crossing, away, bright2, same, later};
  const nlohmann::json j = searchResultToJson(fc, r, {"obs.fits"});
  const auto flagged = [&](int i) {
    for (const auto& f : j["candidates"][i]["flags"])
      if (f == "crosses_brighter") return true;
    return false;
  };
  EXPECT_FALSE(flagged(0));
  EXPECT_TRUE(flagged(1));
  EXPECT_FALSE(flagged(2));
  EXPECT_FALSE(flagged(3));
  EXPECT_FALSE(flagged(4));
  EXPECT_FALSE(flagged(5));
}

TEST(SearchReport, CsvHasOneRowPerCandidateWithFlags) {
  const auto fc = scanCube();
  const nlohmann::json j = searchResultToJson(fc, twoCandidates(), {"obs.fits"});
  test::TempDir dir;
  const std::string path = (dir / "c.csv").string();
  writeCandidatesCsv(path, j);
  std::ifstream in(path);
  std::string header, row1, row2, extra;
  std::getline(in, header);
  std::getline(in, row1);
  std::getline(in, row2);
  EXPECT_FALSE(std::getline(in, extra));
  EXPECT_EQ(
      header,
      "x,y,vx_px_s,vy_px_s,snr,n_frames,fap,rate_deg_day,pa_deg,cluster_cells,flags,method,method_reason");
  EXPECT_EQ(row1.substr(0, 6), "30,20,");
  EXPECT_NE(row2.find("at_sky_rate partial"), std::string::npos);
  // Every row ends with the method and its reason, quoted (it holds commas and quotes, doubled).
  const std::string tail = ",tree,\"auto: tree, clearly faster (estimated exact 9 s, tree 1 s; \"\"9x\"\")\"";
  for (const std::string& row : {row1, row2}) {
    ASSERT_GE(row.size(), tail.size());
    EXPECT_EQ(row.substr(row.size() - tail.size()), tail);
  }
  EXPECT_THROW(writeCandidatesCsv((dir / "no/such/dir/c.csv").string(), j), InputError);
}

/// Fields compared one by one (search::Candidate and SearchResult have no operator==).
void expectSameCandidate(const search::Candidate& a, const search::Candidate& b) {
  EXPECT_EQ(a.x, b.x);
  EXPECT_EQ(a.y, b.y);
  EXPECT_EQ(a.v.vx, b.v.vx);  // exact: the JSON text must carry every bit of the double
  EXPECT_EQ(a.v.vy, b.v.vy);
  EXPECT_EQ(a.ivx, b.ivx);
  EXPECT_EQ(a.ivy, b.ivy);
  EXPECT_EQ(a.sum, b.sum);
  EXPECT_EQ(a.nIn, b.nIn);
  EXPECT_EQ(a.snr, b.snr);
  EXPECT_EQ(a.fap, b.fap);
  EXPECT_EQ(a.clusterCells, b.clusterCells);
}

/// A result whose numbers need all 17 significant digits (1/3, 0.1 + 0.2, a denormal-range FAP).
search::SearchResult awkwardResult() {
  search::SearchResult r = twoCandidates();
  r.grid = {{16.39 + 1.0 / 3.0, -0.1 - 0.2}, 2.0 / 3.0, 3, 2};
  r.candidates[0].sum = 1.0 / 7.0;
  r.candidates[0].snr = 15.000000000000002;
  r.candidates[0].fap = 4.9e-324;
  r.candidates[0].ivx = 2;
  r.candidates[0].ivy = 1;
  r.candidates[0].clusterCells = 17;
  r.candidates[1].fap = 0.1 + 0.2;
  r.candidates[1].x = -3;  // a track that starts off the frame
  r.map = {3, 2, {1.0f / 3.0f, 7.25f, 0.0f, 1e-30f, 12.5f, 3.0f}, {1, 2, 3, 4, 5, 6}, {6, 5, 4, 3, 2, 1}};
  r.snrThreshold = 6.999999999999999;
  r.tRefMjd = 60000.123456789012;
  r.backend = "cpu (2 threads)";
  r.method = st::search::SearchMethod::Tree;
  r.elapsedS = 0.1234567;
  r.cellsAboveThreshold = 123456789012;
  r.sidelobesMerged = 3;
  r.minFrames = 5;
  r.backendNote = "host: plan 2.1 ms\ndevice 0: cube resident (1500 MiB)";
  r.warnings = {"cuda: X failed (out of memory); searched on cpu instead"};
  r.statisticNoise = {1.0604123456789, 0.0053012345, 0.0049876543, 19999};
  return r;
}

TEST(SearchReport, ResultRoundTripsExactlyThroughJsonText) {
  const auto fc = scanCube();
  const search::SearchResult r = awkwardResult();
  nlohmann::json j = searchResultToJson(fc, r, {"obs.fits"});
  j["velocity_map"] = velocityMapToJson(r.map);
  const search::SearchResult back = searchResultFromJson(nlohmann::json::parse(j.dump()));
  EXPECT_EQ(back.grid.centre.vx, r.grid.centre.vx);
  EXPECT_EQ(back.grid.centre.vy, r.grid.centre.vy);
  EXPECT_EQ(back.grid.stepPxS, r.grid.stepPxS);
  EXPECT_EQ(back.grid.nvx, 3);
  EXPECT_EQ(back.grid.nvy, 2);
  EXPECT_EQ(back.trials.total(), r.trials.total());
  EXPECT_EQ(back.snrThreshold, r.snrThreshold);
  EXPECT_EQ(back.tRefMjd, r.tRefMjd);
  EXPECT_EQ(back.backend, r.backend);
  EXPECT_EQ(back.method, r.method);
  EXPECT_EQ(back.methodReason, r.methodReason);
  EXPECT_EQ(back.elapsedS, r.elapsedS);
  EXPECT_EQ(back.cellsAboveThreshold, r.cellsAboveThreshold);
  EXPECT_EQ(back.sidelobesMerged, r.sidelobesMerged);
  EXPECT_EQ(back.minFrames, 5);
  EXPECT_EQ(back.backendNote, r.backendNote);
  EXPECT_EQ(back.warnings, r.warnings);
  EXPECT_EQ(back.statisticNoise.scale, r.statisticNoise.scale);
  EXPECT_EQ(back.statisticNoise.standardError, r.statisticNoise.standardError);
  EXPECT_EQ(back.statisticNoise.mean, r.statisticNoise.mean);
  EXPECT_EQ(back.statisticNoise.cells, 19999);
  ASSERT_EQ(back.candidates.size(), 2u);
  for (std::size_t i = 0; i < 2; ++i)
    expectSameCandidate(back.candidates[i], r.candidates[i]);
  EXPECT_EQ(back.map.nvx, 3);
  EXPECT_EQ(back.map.maxSnr, r.map.maxSnr);
  EXPECT_EQ(back.map.argX, r.map.argX);
  EXPECT_EQ(back.map.argY, r.map.argY);
}

TEST(SearchReport, CandidateRoundTripsAndMissingKeysAreNamed) {
  const auto fc = scanCube();
  const search::SearchResult r = awkwardResult();
  const nlohmann::json c = candidateToJson(fc, r.grid, r.candidates[0]);
  expectSameCandidate(candidateFromJson(nlohmann::json::parse(c.dump())), r.candidates[0]);
  nlohmann::json broken = c;
  broken.erase("fap");
  try {
    (void)candidateFromJson(broken);
    FAIL() << "a candidate without fap was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("'fap'"), std::string::npos) << e.what();
  }
  broken = c;
  broken["snr"] = "high";
  EXPECT_THROW((void)candidateFromJson(broken), InputError);
}

TEST(SearchReport, VelocityMapOfTheWrongSizeAndNonFiniteSnr) {
  search::VelocityMap map{2, 1, {std::numeric_limits<float>::infinity(), 2.0f}, {0, 1}, {0, 0}};
  const search::VelocityMap back = velocityMapFromJson(nlohmann::json::parse(velocityMapToJson(map).dump()));
  EXPECT_TRUE(std::isnan(back.maxSnr[0]));  // documented: non-finite values come back as NaN
  EXPECT_EQ(back.maxSnr[1], 2.0f);
  nlohmann::json j = velocityMapToJson(map);
  j["nvx"] = 3;
  EXPECT_THROW((void)velocityMapFromJson(j), InputError);
  // A result without a map or candidates (a session's "search" member) reads with both empty.
  nlohmann::json noCandidates = searchResultToJson(scanCube(), awkwardResult(), {});
  noCandidates.erase("candidates");
  const auto result = searchResultFromJson(noCandidates);
  EXPECT_TRUE(result.candidates.empty());
  EXPECT_TRUE(result.map.maxSnr.empty());
}

TEST(SearchReport, JsonFileIsWrittenAtomically) {
  test::TempDir dir;
  const std::string path = (dir / "r.json").string();
  writeJsonFile(path, nlohmann::json{{"a", 1}});
  writeJsonFile(path, nlohmann::json{{"a", 2}});
  std::ifstream in(path);
  EXPECT_EQ(nlohmann::json::parse(in)["a"], 2);
  EXPECT_FALSE(std::filesystem::exists(path + ".tmp"));
}

}  // namespace
}  // namespace st::report

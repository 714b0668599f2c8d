#include <gtest/gtest.h>

#include <fstream>
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
  r.method = "tree";
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

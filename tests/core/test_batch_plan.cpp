// The bookkeeping of `synthtrack-cli batch` (issue 17): cutting a night into overlapping cubes, manifests,
// the digest that decides what a rerun skips, atomic output folders, the merged catalogue.
#include <gtest/gtest.h>

#include <fstream>
#include <thread>

#include "st/batch/batch_queue.hpp"
#include "st/batch/batch_state.hpp"
#include "st/batch/catalogue.hpp"
#include "st/batch/observation_list.hpp"
#include "st/common/error.hpp"
#include "test_support.hpp"

namespace st {
namespace {

void touch(const std::filesystem::path& p, const std::string& text = "x") {
  std::ofstream(p) << text;
}

TEST(BatchPlan, SplitRangesOverlapAndEndAtTheLastFrame) {
  using R = std::vector<std::pair<int, int>>;
  EXPECT_EQ(batch::splitRanges(10, 4, 1), (R{{0, 4}, {3, 7}, {6, 10}}));
  EXPECT_EQ(batch::splitRanges(11, 4, 1), (R{{0, 4}, {3, 7}, {6, 10}, {7, 11}}));  // last one overlaps more
  EXPECT_EQ(batch::splitRanges(3, 4, 1), (R{{0, 3}}));
  // Every pair of consecutive cubes shares at least `overlap` frames: a mover is whole in one of them.
  for (const auto& [n, k] : {std::pair{1500, 300}, std::pair{997, 100}}) {
    const auto r = batch::splitRanges(8000, n, k);
    EXPECT_EQ(r.front().first, 0);
    EXPECT_EQ(r.back().second, 8000);
    for (std::size_t i = 1; i < r.size(); ++i)
      EXPECT_GE(r[i - 1].second - r[i].first, k);
  }
  EXPECT_THROW(batch::splitRanges(10, 4, 4), InputError);
  EXPECT_THROW(batch::splitRanges(10, 1, 0), InputError);
}

TEST(BatchPlan, SplitFolderNamesCubesAndGroupsThem) {
  test::TempDir dir;
  std::filesystem::create_directories(dir / "night");
  for (int i = 0; i < 10; ++i)
    touch(dir / "night" / std::string("f").append(std::to_string(100 + i)).append(".fits"));
  touch(dir / "night" / "notes.txt");
  const auto obs = batch::observationsFromInputs({(dir / "night").string() + "/"});
  ASSERT_EQ(obs.size(), 1u);
  EXPECT_EQ(obs[0].name, "night");
  const auto cubes = batch::splitObservation(obs[0], 4, 1);
  ASSERT_EQ(cubes.size(), 3u);
  EXPECT_EQ(cubes[1].name, "night_c001");
  EXPECT_EQ(cubes[1].group, "night");
  ASSERT_EQ(cubes[1].inputs.size(), 4u);
  EXPECT_EQ(std::filesystem::path(cubes[1].inputs[0]).filename(), "f103.fits");
  EXPECT_THROW(batch::splitObservation({"one", {(dir / "night" / "f100.fits").string()}}, 4, 1), InputError);
}

TEST(BatchPlan, ManifestJsonAndCsv) {
  test::TempDir dir;
  touch(dir / "a.fits", std::string(100, 'a'));
  touch(dir / "b.fits", std::string(300, 'b'));
  std::ofstream(dir / "m.json") << R"([{"inputs": "a.fits", "params": {"vmax_deg_day": 40, "snr": 6.5}},
                                       {"name": "second", "inputs": ["b.fits"], "flat": "flat.fits"}])";
  const auto j = batch::readManifest((dir / "m.json").string());
  ASSERT_EQ(j.size(), 2u);
  EXPECT_EQ(j[0].name, "a");
  EXPECT_EQ(j[0].params.at("vmax-deg-day"), "40");
  EXPECT_EQ(j[0].params.at("snr"), "6.5");
  EXPECT_EQ(j[0].inputs[0], (dir / "a.fits").string());  // relative to the manifest
  EXPECT_EQ(j[1].name, "second");
  EXPECT_EQ(j[1].flat.size(), 1u);
  EXPECT_EQ(batch::largestFirst(j), (std::vector<std::size_t>{1, 0}));
  std::ofstream(dir / "m.csv") << "# a night\ninputs,vmax-px-s,group\na.fits;b.fits,2.5,n1\nb.fits,,n1\n";
  const auto c = batch::readManifest((dir / "m.csv").string());
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(c[0].inputs.size(), 2u);
  EXPECT_EQ(c[0].params.at("vmax-px-s"), "2.5");
  EXPECT_EQ(c[1].params.count("vmax-px-s"), 0u);
  EXPECT_EQ(c[1].name, "b");
  EXPECT_EQ(c[0].group, "n1");
  std::ofstream(dir / "bad.csv") << "inputs,snr\na.fits\n";
  EXPECT_THROW(batch::readManifest((dir / "bad.csv").string()), InputError);
  std::ofstream(dir / "bad.json") << R"([{"name": "x"}])";
  EXPECT_THROW(batch::readManifest((dir / "bad.json").string()), InputError);
}

TEST(BatchState, DigestFollowsInputsAndOptions) {
  test::TempDir dir;
  touch(dir / "a.fits", "1234");
  const batch::Observation obs{"a", {(dir / "a.fits").string()}};
  const std::string d = batch::inputDigest(obs, {{"snr", "7"}});
  EXPECT_EQ(d.size(), 16u);
  EXPECT_EQ(d, batch::inputDigest(obs, {{"snr", "7"}}));
  EXPECT_NE(d, batch::inputDigest(obs, {{"snr", "6"}}));
  touch(dir / "a.fits", "12345");  // size changes
  EXPECT_NE(d, batch::inputDigest(obs, {{"snr", "7"}}));
}

TEST(BatchState, StagedFolderAppearsWholeOrNotAtAll) {
  test::TempDir dir;
  const auto final = dir / "observations" / "a";
  {
    batch::StagedFolder f(final);
    touch(f.path() / "candidates.json", "{}");
    EXPECT_FALSE(std::filesystem::exists(final));
  }  // not committed: nothing left
  EXPECT_FALSE(std::filesystem::exists(final));
  EXPECT_TRUE(std::filesystem::is_empty(dir / "observations"));
  for (const char* digest : {"d1", "d2"}) {
    batch::StagedFolder f(final);
    touch(f.path() / batch::kResultFile, "{}");
    batch::writeJsonAtomically(f.path() / batch::kDigestFile, {{"digest", digest}});
    f.commit();
  }
  EXPECT_TRUE(batch::outputComplete(final, "d2"));  // the second replaced the first
  EXPECT_FALSE(batch::outputComplete(final, "d1"));
  std::filesystem::remove(final / batch::kResultFile);
  EXPECT_FALSE(batch::outputComplete(final, "d2"));
}

nlohmann::json result(double tRefMjd, std::vector<std::array<double, 5>> cands) {
  nlohmann::json r{
      {"t_ref_mjd", tRefMjd}, {"grid", {{"step_px_s", 0.1}}}, {"candidates", nlohmann::json::array()}};
  for (const auto& c : cands)
    r["candidates"].push_back(
        {{"x", c[0]}, {"y", c[1]}, {"vx_px_s", c[2]}, {"vy_px_s", c[3]}, {"snr", c[4]}});
  return r;
}

TEST(Catalogue, OneObjectInOverlappingCubesIsOneEntry) {
  using S = batch::Outcome::Status;
  const double dtDays = 60.0 / 86400.0;  // the second cube's epoch is 60 s later
  // The same mover (2, 0.5 px/s) in both cubes of a night, and a different one in the second only.
  std::vector<batch::Outcome> o{
      {"n_c000", "n", {"a"}, S::Done, {}, result(60000.0, {{50, 40, 2.0, 0.5, 12.0}})},
      {"n_c001",
       "n",
       {"b"},
       S::Done,
       {},
       result(60000.0 + dtDays, {{170, 70, 2.05, 0.5, 15.0}, {10, 10, 0.0, 3.0, 8.0}})},
      {"other", "", {"c"}, S::Done, {}, result(60000.0, {{50, 40, 2.0, 0.5, 9.0}})},
      {"bad", "", {"d"}, S::Failed, "truncated", {}},
      {"late", "", {"e"}, S::NotDone, "rank 2 died", {}}};
  const nlohmann::json cat = batch::mergeCatalogue(o);
  ASSERT_EQ(cat["candidates"].size(), 3u) << cat.dump(2);
  // Ordered by observation then SNR; the merged entry quotes its brightest detection.
  EXPECT_EQ(cat["candidates"][0]["observation"], "n_c001");
  EXPECT_EQ(cat["candidates"][0]["snr"], 15.0);
  EXPECT_EQ(cat["candidates"][0]["seen_in"].size(), 2u);
  EXPECT_EQ(cat["candidates"][1]["observation"], "n_c001");
  EXPECT_EQ(cat["candidates"][2]["observation"], "other");  // another group: not merged
  ASSERT_EQ(cat["errors"].size(), 1u);
  EXPECT_EQ(cat["errors"][0]["error"], "truncated");
  ASSERT_EQ(cat["not_done"].size(), 1u);
  EXPECT_EQ(cat["not_done"][0]["observation"], "late");
  EXPECT_EQ(cat["observations"].size(), 5u);
}

/// A cube's result with its frame span [t0, t0 + spanS] (t_ref in the middle) and candidates whose position
/// is given at t_ref.
nlohmann::json cube(double t0Mjd, double spanS, std::vector<std::array<double, 5>> cands) {
  nlohmann::json r = result(t0Mjd + 0.5 * spanS / 86400.0, std::move(cands));
  r["t_first_mjd"] = t0Mjd;
  r["t_last_mjd"] = t0Mjd + spanS / 86400.0;
  return r;
}

TEST(Catalogue, AMoverAcrossCubesIsOneEntryEvenWhereACubeSawItPartly) {
  using S = batch::Outcome::Status;
  // Cubes of 10 s sharing 3 s: [0,10], [7,17], [14,24], [21,31] s. The mover: x = 0 + 3.46 t, y = 20 + 2 t
  // (t in s from the first frame).
  const double t0 = 60000.0, day = 86400.0;
  const auto at = [](double t) { return std::array<double, 2>{3.46 * t, 20.0 + 2.0 * t}; };
  const auto mover = [&](double tRef, double vx, double vy, double snr) {
    const auto p = at(tRef);
    return std::array<double, 5>{p[0], p[1], vx, vy, snr};
  };
  // Cube 0 sees it for its last seconds only: a partial detection, the position of its evidence right but
  // the velocity 1 px/s off (its track agrees within ~2 px over the 3 shared seconds).
  auto partial = mover(5.0, 2.46, 2.0, 7.5);
  partial[0] += (3.46 - 2.46) * (8.5 - 5.0);  // right at 8.5 s, the middle of the frames it shares
  std::vector<batch::Outcome> o{
      {"n_c000", "n", {"a"}, S::Done, {}, cube(t0, 10.0, {partial, {5.0, 5.0, 0.0, 0.0, 9.0}})},
      {"n_c001", "n", {"b"}, S::Done, {}, cube(t0 + 7.0 / day, 10.0, {mover(12.0, 3.5, 2.02, 11.0)})},
      {"n_c002", "n", {"c"}, S::Done, {}, cube(t0 + 14.0 / day, 10.0, {mover(19.0, 3.45, 1.98, 12.0)})},
      // The brightest in the last cube: the chain reaches cube 0 only through cubes 1 and 2.
      {"n_c003", "n", {"d"}, S::Done, {}, cube(t0 + 21.0 / day, 10.0, {mover(26.0, 3.44, 2.0, 13.0)})}};
  const nlohmann::json cat = batch::mergeCatalogue(o);
  ASSERT_EQ(cat["candidates"].size(), 2u) << cat.dump(2);
  const auto& e =
      cat["candidates"][0]["observation"] == "n_c003" ? cat["candidates"][0] : cat["candidates"][1];
  EXPECT_EQ(e["observation"], "n_c003");
  EXPECT_EQ(e["snr"], 13.0);
  EXPECT_EQ(e["seen_in"].size(), 4u) << e.dump(2);

  // Tracks that meet in the middle of the shared frames but are 10 px apart at their ends: two objects.
  std::vector<batch::Outcome> crossing{
      {"n_c000", "n", {"a"}, S::Done, {}, cube(t0, 10.0, {mover(5.0, 3.46, 2.0, 9.0)})},
      {"n_c001",
       "n",
       {"b"},
       S::Done,
       {},
       cube(t0 + 7.0 / day, 10.0, {{at(8.5)[0], at(8.5)[1] - 14.0, 0.0, -4.0, 8.0}})}};
  EXPECT_EQ(batch::mergeCatalogue(crossing)["candidates"].size(), 2u);
}

TEST(BatchQueue, HandsOutInOrderAndNamesWhatADeadWorkerHeld) {
  batch::BatchQueue q({2, 0, 1});
  EXPECT_EQ(q.next(1), 2u);
  EXPECT_EQ(q.next(2), 0u);
  q.finished(1);
  EXPECT_EQ(q.next(1), 1u);
  EXPECT_EQ(q.lose(2), 0u);
  EXPECT_EQ(q.lose(2), std::nullopt);
  EXPECT_EQ(q.next(3), std::nullopt);
  EXPECT_EQ(q.inFlight(), 1u);
  EXPECT_EQ(batch::progressLine(12, 480, 2, 1, 10, 360.0),
            "12/480 observations (2 skipped, 1 failed), 100.0/h, ETA 4h40m");
  EXPECT_EQ(batch::progressLine(0, 4, 0, 0, 0, 0.0), "0/4 observations, ETA -");
}

}  // namespace
}  // namespace st

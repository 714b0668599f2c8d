// The candidate inspector on small synthetic cubes (one dot moving along a known track, noise-free, so
// every number has an exact value): the stamp at the dot's velocity peaks at the dot with SNR
// N / (sigma_F sqrt N), the sky-rate stamp does not; the segment strip has K = 4 equal segments with the
// SNRs a steady source gives, and marks the segments a transient misses; the movie has one cutout per
// frame with the dot at its centre and scrubs and plays; the artifact flags are stored on the candidate;
// known objects load from a CSV (errors name the file and line) and match through the WCS service.
#include <gtest/gtest.h>

#include <QSlider>
#include <QTreeWidget>
#include <cmath>
#include <fstream>
#include <iomanip>

#include "candidate_inspector.hpp"
#include "stamp_strip.hpp"
#include "test_support.hpp"
#include "ui_test_support.hpp"

using namespace st;
using namespace st::ui;

namespace {

constexpr double kSigmaF = 0.05;
constexpr std::size_t kFrames = 40;
constexpr Velocity kV{8.0, 0.0};  // 31 px over the 3.9 s of the cube

/// An observation holding `cube` as raw, filtered and unfiltered frames, one candidate on the dot's track
/// at (32, 32) and velocity kV, selected.
void setUp(Observation& obs, FrameCube cube) {
  auto raw = std::make_shared<const FrameCube>(cube);
  obs.setRaw(raw, "synthetic");
  auto view = std::make_shared<PreparedView>();
  auto filtered = std::make_shared<search::FilteredCube>();
  filtered->frames = std::move(cube);
  filtered->sigmaF = kSigmaF;
  filtered->psfFwhmPx = 2.5;
  view->filtered = filtered;
  view->unfiltered = filtered;
  obs.setPrepared(view);
  auto result = std::make_shared<search::SearchResult>();
  search::Candidate c;
  c.x = 32;
  c.y = 32;
  c.v = kV;
  c.nIn = static_cast<int>(kFrames);
  c.snr = static_cast<double>(kFrames) / (kSigmaF * std::sqrt(static_cast<double>(kFrames)));
  result->candidates.push_back(c);
  obs.setResult(result);
}

std::pair<int, int> argMax(const Image& im) {
  std::size_t best = 0;
  for (std::size_t k = 1; k < im.size(); ++k)
    if (im.pixels[k] > im.pixels[best]) best = k;
  return {static_cast<int>(best % im.width), static_cast<int>(best / im.width)};
}

bool inspect(Observation& obs, CandidateInspector& inspector) {
  bool done = false;
  const auto conn = QObject::connect(&inspector, &CandidateInspector::inspected, [&done] { done = true; });
  obs.setSelected(0);
  const bool ok = test::waitFor([&] { return done; }, 10000);
  QObject::disconnect(conn);
  return ok;
}

}  // namespace

TEST(CandidateInspector, StampsSegmentsMovieAndFlagsOfAMovingDot) {
  Observation obs;
  setUp(obs, test::movingDotCube(64, 64, kFrames, kV, 32, 32));
  CoreServices services;
  CandidateInspector inspector(&obs, &services);
  inspector.setStoreFlags(false);  // a setting: the previous run may have left it on
  ASSERT_TRUE(inspect(obs, inspector)) << inspector.statusText().toStdString();
  const auto& in = *inspector.inspection();
  const int half = in.trackStamp.width / 2;

  // At the dot's velocity every frame adds at the centre: SNR = N / (sigma_F sqrt N), exactly.
  const double full = kFrames / (kSigmaF * std::sqrt(static_cast<double>(kFrames)));
  EXPECT_EQ(argMax(in.trackStamp), std::make_pair(half, half));
  EXPECT_NEAR(in.trackSnr, full, 1e-3 * full);
  // At the sky rate (0) the dot streaks: only the frames with |vx t| < 0.5 px reach the centre (2 of 40).
  EXPECT_NEAR(in.skySnr, 2.0 / (kSigmaF * std::sqrt(static_cast<double>(kFrames))), 1e-3);
  float skyMax = 0.0f;
  for (float p : in.skyStamp.pixels)
    skyMax = std::max(skyMax, p);
  EXPECT_LT(skyMax, 0.1 * full);
  ASSERT_EQ(inspector.stamps()->tileCount(), 2);

  // Four equal segments of 10 frames, each SNR 10 / (sigma_F sqrt 10) as a steady source predicts.
  ASSERT_EQ(in.segments.segments.size(), 4u);
  for (const auto& s : in.segments.segments) {
    EXPECT_EQ(s.framesInside, 10u);
    EXPECT_NEAR(s.forcedSnr, 10.0 / (kSigmaF * std::sqrt(10.0)), 1e-3);
    EXPECT_NEAR(s.expectedSnr, s.forcedSnr, 1e-3);
    EXPECT_FALSE(s.missing);
  }
  EXPECT_FALSE(in.segments.flagged());
  ASSERT_EQ(inspector.segmentStrip()->tileCount(), 4);
  for (int k = 0; k < 4; ++k)
    EXPECT_FALSE(inspector.segmentStrip()->tile(k).flagged);

  // One cutout per frame, the dot at its centre in each.
  ASSERT_EQ(in.movie.size(), kFrames);
  for (const auto& cut : in.movie)
    EXPECT_FLOAT_EQ(cut.at(half, half), 1.0f);
  inspector.movieSlider()->setValue(7);
  ASSERT_EQ(inspector.movieView()->tileCount(), CandidateInspector::kMovieTiles);
  EXPECT_EQ(inspector.movieCurrentTile(), CandidateInspector::kMovieTiles / 2);
  const auto& current = inspector.movieView()->tile(inspector.movieCurrentTile());
  EXPECT_EQ(current.image->pixels, in.movie[7].pixels);
  EXPECT_TRUE(current.caption.startsWith("▶ 7")) << current.caption.toStdString();
  inspector.setPlaying(true);
  EXPECT_TRUE(inspector.playing());
  EXPECT_TRUE(test::waitFor([&] { return inspector.movieSlider()->value() != 7; }, 3000));
  inspector.setPlaying(false);
  EXPECT_FALSE(inspector.playing());

  // Every check ran (the six artifact checks, the known-object and the static-source check) and nothing fired
  // on a clean dot in the middle. Inspecting changed nothing on the
  // candidate until "Store on candidate" is checked; then the flags are on it.
  ASSERT_EQ(in.flags.size(), 8u);
  for (const auto& f : in.flags)
    EXPECT_FALSE(f.triggered) << vet::toString(f.kind) << ": " << f.evidence;
  ASSERT_EQ(inspector.flagList()->topLevelItemCount(), 8);
  const auto* state = obs.candidateState(0);
  ASSERT_TRUE(state);
  EXPECT_TRUE(state->artifacts.empty());
  int changes = 0;
  QObject::connect(&obs, &Observation::candidateStateChanged, [&changes] { ++changes; });
  inspector.setStoreFlags(true);
  EXPECT_EQ(changes, 1);
  ASSERT_EQ(state->artifacts.size(), 8u);
  inspector.refresh();  // the same flags again: stored, but no change signalled
  ASSERT_TRUE(test::waitFor([&] { return !inspector.busy(); }, 5000));
  QApplication::processEvents();
  EXPECT_EQ(changes, 1);
  EXPECT_EQ(state->artifacts[3].kind, vet::ArtifactKind::Edge);
}

TEST(CandidateInspector, MarksTheSegmentsATransientMisses) {
  // The dot shows only in the first 10 frames (a flash): segments 2-4 miss it.
  FrameCube cube = test::movingDotCube(64, 64, kFrames, kV, 32, 32);
  for (std::size_t n = 10; n < kFrames; ++n)
    std::fill(cube.frame(n), cube.frame(n) + cube.framePixels(), 0.0f);
  Observation obs;
  setUp(obs, std::move(cube));
  CoreServices services;
  CandidateInspector inspector(&obs, &services);
  inspector.setStoreFlags(true);
  ASSERT_TRUE(inspect(obs, inspector));
  const auto& seg = inspector.inspection()->segments;
  ASSERT_EQ(seg.segments.size(), 4u);
  EXPECT_FALSE(seg.segments[0].missing);
  for (int k = 1; k < 4; ++k) {
    EXPECT_TRUE(seg.segments[static_cast<std::size_t>(k)].missing) << k;
    EXPECT_TRUE(inspector.segmentStrip()->tile(k).flagged) << k;
  }
  EXPECT_TRUE(seg.missingSignal);
  EXPECT_TRUE(seg.fluxInconsistent);
  const auto& transient = inspector.inspection()->flags[static_cast<int>(vet::ArtifactKind::Transient)];
  EXPECT_EQ(transient.kind, vet::ArtifactKind::Transient);
  EXPECT_TRUE(transient.triggered);
  EXPECT_NE(transient.evidence.find("segment 2"), std::string::npos) << transient.evidence;
  EXPECT_TRUE(obs.candidateState(0)->artifacts[5].triggered);
}

TEST(CandidateInspector, KnownObjectsLoadMatchAndReportBadLines) {
  Observation obs;
  setUp(obs, test::movingDotCube(64, 64, kFrames, kV, 32, 32));
  CoreServices services;
  // A tangent-plane stand-in for a WCS: 1 arcsec per pixel around (150, 2) deg.
  services.pixelToSky = [](const FrameCube&, double x, double y) -> std::optional<std::pair<double, double>> {
    return std::make_pair(150.0 + x / 3600.0, 2.0 + y / 3600.0);
  };
  CandidateInspector inspector(&obs, &services);
  ASSERT_TRUE(inspect(obs, inspector));
  test::TempDir dir;
  const double mjd = obs.raw()->tRefMjd();
  const std::string good = (dir / "known.csv").string();
  std::ofstream(good) << "name,ra_deg,dec_deg,ra_rate_arcsec_min,dec_rate_arcsec_min,epoch_mjd\n"
                      << "far away,151.0,3.0,0,0," << std::setprecision(12) << mjd << "\n"
                      << "2026 AB,150.00888889,2.00888889,0,0," << mjd << "\n";
  bool loaded = false;
  bool reinspected = false;
  QObject::connect(&inspector, &CandidateInspector::knownObjectsLoaded, [&] { loaded = true; });
  QObject::connect(&inspector, &CandidateInspector::inspected, [&] { reinspected = loaded; });
  inspector.loadKnownObjects(QString::fromStdString(good));
  ASSERT_TRUE(test::waitFor([&] { return reinspected; }, 10000)) << inspector.statusText().toStdString();
  EXPECT_EQ(inspector.knownObjectCount(), 2u);
  const auto& flag = inspector.inspection()->flags.back();
  EXPECT_EQ(flag.kind, vet::ArtifactKind::KnownObject);
  EXPECT_TRUE(flag.triggered) << flag.evidence;
  EXPECT_LT(flag.value, 1.0);  // (32, 32) px = (32", 32") from the origin, where 2026 AB is
  EXPECT_NE(flag.evidence.find("2026 AB"), std::string::npos);

  const std::string bad = (dir / "bad.csv").string();
  std::ofstream(bad) << "name,ra_deg,dec_deg,ra_rate_deg_day,dec_rate_deg_day,epoch_mjd\n"
                     << "ok,10,20,0,0,60000\n"
                     << "broken,ten,20,0,0,60000\n";
  QString error;
  QObject::connect(&inspector, &CandidateInspector::knownObjectsFailed, [&](const QString& m) { error = m; });
  inspector.loadKnownObjects(QString::fromStdString(bad));
  ASSERT_TRUE(test::waitFor([&] { return !error.isEmpty(); }, 5000));
  EXPECT_TRUE(error.contains("bad.csv")) << error.toStdString();
  EXPECT_TRUE(error.contains("line 3")) << error.toStdString();  // the line at fault
  EXPECT_EQ(inspector.knownObjectCount(), 2u);                   // the previous list is kept
}

ST_UI_TEST_MAIN()

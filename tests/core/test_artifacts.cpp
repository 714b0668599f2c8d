// Artifact flags (issue 8): each check fires on a synthetic case built for it and stays quiet on a clean one,
// following the track over the frames (not only its position at t_ref) with the stars moving at the sky rate.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "st/common/error.hpp"
#include "st/vet/artifacts.hpp"

namespace st::vet {
namespace {

constexpr int kFrames = 51;
const Velocity kSky{0.5, 0.0};  // stars drift +x by 0.5 px/s

/// 200 x 200 frames at t = -10 ... +10 s, no stars.
ArtifactContext baseContext() {
  ArtifactContext ctx;
  ctx.width = 200;
  ctx.height = 200;
  for (int n = 0; n < kFrames; ++n)
    ctx.timesS.push_back(-10.0 + 20.0 * n / (kFrames - 1));
  ctx.skyRate = kSky;
  ctx.psfFwhmPx = 3.0;
  return ctx;
}

detect::Star star(double x, double y, double snr, bool saturated, std::vector<int> bleed = {}) {
  detect::Star s;
  s.x = x;
  s.y = y;
  s.snr = snr;
  s.flux = snr * 100.0;
  s.saturated = saturated;
  s.bleedColumns = std::move(bleed);
  return s;
}

FrameCube cubeFor(const ArtifactContext& ctx) {
  FrameCube cube(ctx.width, ctx.height, ctx.timesS.size());
  for (std::size_t n = 0; n < ctx.timesS.size(); ++n)
    cube.info()[n].mjdMid = 60000.0 + ctx.timesS[n] / 86400.0;
  return cube;
}

TEST(Artifacts, ChargeLeakageOnABleedColumnFollowingTheSky) {
  ArtifactContext ctx = baseContext();
  ctx.stars = {star(100.0, 50.0, 500.0, true, {99, 100, 101})};
  const ArtifactParams p;
  // Moving with the stars in x (on the bleed columns in every frame), along the column in y.
  const ArtifactFlag on = checkChargeLeakage(ctx, {100.0, 120.0, {kSky.vx, 2.0}}, p);
  EXPECT_TRUE(on.triggered) << on.evidence;
  EXPECT_DOUBLE_EQ(on.value, 1.0);
  EXPECT_NE(on.evidence.find("column"), std::string::npos) << on.evidence;
  // Far from every column and row of the saturated star.
  const ArtifactFlag off = checkChargeLeakage(ctx, {150.0, 120.0, {kSky.vx, 2.0}}, p);
  EXPECT_FALSE(off.triggered) << off.evidence;
  EXPECT_DOUBLE_EQ(off.value, 0.0);
  // The same track next to an unsaturated star: no leakage.
  ctx.stars = {star(100.0, 50.0, 500.0, false)};
  EXPECT_FALSE(checkChargeLeakage(ctx, {100.0, 120.0, {kSky.vx, 2.0}}, p).triggered);
}

TEST(Artifacts, ChargeLeakageIsJudgedAlongTheTrackNotOnlyAtTRef) {
  ArtifactContext ctx = baseContext();
  ctx.stars = {star(100.0, 50.0, 500.0, true, {100})};
  const ArtifactParams p;
  // x - column(t) = 3 + 0.5 t: 3 px off the column at t_ref, within 1.5 px for t in [-9, -3] (30% of the
  // span).
  const Track track{103.0, 150.0, {kSky.vx + 0.5, 1.0}};
  const ArtifactFlag f = checkChargeLeakage(ctx, track, p);
  EXPECT_TRUE(f.triggered) << f.evidence;
  EXPECT_NEAR(f.value, 0.3, 1.5 / kFrames);
  // Raising the fraction needed above 30% silences it.
  ArtifactParams strict;
  strict.leakageMinFraction = 0.5;
  EXPECT_FALSE(checkChargeLeakage(ctx, track, strict).triggered);
}

TEST(Artifacts, ChargeLeakageOnTheRowOfASaturatedStar) {
  ArtifactContext ctx = baseContext();
  ctx.stars = {star(40.0, 60.0, 500.0, true)};
  const ArtifactFlag f = checkChargeLeakage(ctx, {150.0, 60.5, {-1.0, 0.0}}, ArtifactParams{});
  EXPECT_TRUE(f.triggered) << f.evidence;
  EXPECT_NE(f.evidence.find("row"), std::string::npos) << f.evidence;
}

TEST(Artifacts, NearABrightStarWithTheClosestApproach) {
  ArtifactContext ctx = baseContext();
  ctx.stars = {star(100.0, 100.0, 200.0, false)};
  const ArtifactParams p;  // radius 4 FWHM = 12 px
  // Relative to the star the track moves (+1, 0) px/s from x-offset -10 at t=-10 ... passes 5 px above it.
  const ArtifactFlag near = checkBrightStar(ctx, {100.0, 105.0, {kSky.vx + 1.0, 0.0}}, p);
  EXPECT_TRUE(near.triggered) << near.evidence;
  EXPECT_NEAR(near.value, 5.0, 1e-9);
  const ArtifactFlag far = checkBrightStar(ctx, {100.0, 140.0, {kSky.vx + 1.0, 0.0}}, p);
  EXPECT_FALSE(far.triggered) << far.evidence;
  EXPECT_NEAR(far.value, 40.0, 1e-9);
  // A faint star is not a bright star.
  ctx.stars = {star(100.0, 100.0, 20.0, false)};
  EXPECT_FALSE(checkBrightStar(ctx, {100.0, 105.0, {kSky.vx + 1.0, 0.0}}, p).triggered);
}

TEST(Artifacts, DiffractionSpikesAlongTheDetectorAxesAndAtGivenAngles) {
  ArtifactContext ctx = baseContext();
  ctx.stars = {star(100.0, 100.0, 300.0, false)};
  ArtifactParams p;  // spikes at 0 and 90 deg, 2 px wide, 60 px long
  // 30 px right of the star, 1 px below the horizontal spike, moving along it (20..40 px out).
  const ArtifactFlag on = checkDiffraction(ctx, {130.0, 101.0, {kSky.vx + 1.0, 0.0}}, p);
  EXPECT_TRUE(on.triggered) << on.evidence;
  EXPECT_DOUBLE_EQ(on.value, 1.0);
  EXPECT_FALSE(checkDiffraction(ctx, {130.0, 110.0, {kSky.vx + 1.0, 0.0}}, p).triggered);
  // Beyond the spike's length.
  EXPECT_FALSE(checkDiffraction(ctx, {100.0, 180.0, {kSky.vx, 0.2}}, p).triggered);
  // A diagonal track along (1, 1) from the star: on a 45 deg spike only.
  const Track diagonal{125.0, 126.0, {kSky.vx + 0.5, 0.5}};
  EXPECT_FALSE(checkDiffraction(ctx, diagonal, p).triggered);
  p.spikeAnglesDeg = {45.0, 135.0};
  const ArtifactFlag d = checkDiffraction(ctx, diagonal, p);
  EXPECT_TRUE(d.triggered) << d.evidence;
  EXPECT_NE(d.evidence.find("45 deg"), std::string::npos) << d.evidence;
}

TEST(Artifacts, EdgeMarginAndTracksLeavingTheFrame) {
  const ArtifactContext ctx = baseContext();
  const ArtifactParams p;  // margin 2 FWHM = 6 px
  const ArtifactFlag edge = checkEdge(ctx, {3.0, 100.0, {0.0, 0.0}}, p);
  EXPECT_TRUE(edge.triggered) << edge.evidence;
  EXPECT_DOUBLE_EQ(edge.value, 3.5);  // to the outer border of pixel 0
  const ArtifactFlag inside = checkEdge(ctx, {100.0, 100.0, {1.0, 0.0}}, p);
  EXPECT_FALSE(inside.triggered) << inside.evidence;
  EXPECT_DOUBLE_EQ(inside.value, 89.5);  // x = 110 at t = +10
  // Fine at t_ref, out of the frame by the end.
  const ArtifactFlag leaves = checkEdge(ctx, {190.0, 100.0, {2.0, 0.0}}, p);
  EXPECT_TRUE(leaves.triggered);
  EXPECT_LT(leaves.value, 0.0);
  EXPECT_NE(leaves.evidence.find("outside the frame"), std::string::npos) << leaves.evidence;
}

TEST(Artifacts, MaskedPixelsAlongTheTrack) {
  ArtifactContext ctx = baseContext();
  FrameCube cube = cubeFor(ctx);
  cube.mask().assign(cube.pixels().size(), 0);
  for (std::size_t n = 0; n < cube.frameCount(); ++n) {
    for (int y = 0; y < cube.height(); ++y)
      cube.mask()[n * cube.framePixels() + y * cube.width() + 50] = 1;
  }
  ctx.frames = &cube;
  const ArtifactParams p;  // disc of 1 FWHM = 3 px: the masked column is 7 of 29 samples
  const ArtifactFlag on = checkMasked(ctx, {50.0, 100.0, {0.0, 2.0}}, p);
  EXPECT_TRUE(on.triggered) << on.evidence;
  EXPECT_NEAR(on.value, 7.0 / 29.0, 1e-12);
  const ArtifactFlag off = checkMasked(ctx, {80.0, 100.0, {0.0, 2.0}}, p);
  EXPECT_FALSE(off.triggered) << off.evidence;
  EXPECT_DOUBLE_EQ(off.value, 0.0);
  // Crossing the column quickly touches few samples.
  EXPECT_FALSE(checkMasked(ctx, {50.0, 100.0, {3.0, 0.0}}, p).triggered);
}

TEST(Artifacts, TransientCarriedByOneFrameButNotASteadySource) {
  ArtifactContext ctx = baseContext();
  FrameCube steady = cubeFor(ctx);
  std::mt19937 rng(7);
  std::normal_distribution<float> noise(0.0f, 1.0f);
  for (auto& v : steady.pixels())
    v = noise(rng);
  FrameCube flash = steady;
  const Track track{100.0, 100.0, {1.2, -0.7}};
  // Steady source: SNR 10 over 51 frames (amplitude 10/sqrt(51) per frame at the IPSA samples).
  const double a = 10.0 / std::sqrt(static_cast<double>(kFrames));
  for (std::size_t n = 0; n < steady.frameCount(); ++n) {
    const int x = static_cast<int>(std::lround(track.x + std::round(track.v.vx * ctx.timesS[n])));
    const int y = static_cast<int>(std::lround(track.y + std::round(track.v.vy * ctx.timesS[n])));
    steady.frame(n)[y * steady.width() + x] += static_cast<float>(a);
    if (n == 17) flash.frame(n)[y * flash.width() + x] += 60.0f;  // a cosmic ray on the track
  }
  const ArtifactParams p;
  ctx.frames = &steady;
  const ArtifactFlag quiet = checkTransient(ctx, track, p, nullptr);
  EXPECT_FALSE(quiet.triggered) << quiet.evidence;
  EXPECT_LT(quiet.value, 0.35);
  ctx.frames = &flash;
  const ArtifactFlag fired = checkTransient(ctx, track, p, nullptr);
  EXPECT_TRUE(fired.triggered) << fired.evidence;
  EXPECT_GT(fired.value, 0.8);
  // The segment report's flags fire it too, with their reasons.
  SegmentReport seg;
  seg.missingSignal = true;
  seg.reasons = {"segment 3 misses the signal"};
  ctx.frames = &steady;
  const ArtifactFlag bySegments = checkTransient(ctx, track, p, &seg);
  EXPECT_TRUE(bySegments.triggered);
  EXPECT_NE(bySegments.evidence.find("segment 3 misses"), std::string::npos);
}

TEST(Artifacts, AllChecksInOrderWithEvidenceEvenWhenQuiet) {
  ArtifactContext ctx = baseContext();
  ctx.stars = {star(20.0, 20.0, 500.0, true, {20})};
  const auto flags = checkArtifacts(ctx, {120.0, 130.0, {1.0, 1.0}}, ArtifactParams{});
  ASSERT_EQ(flags.size(), 6u);
  EXPECT_EQ(flags[0].kind, ArtifactKind::ChargeLeakage);
  EXPECT_EQ(flags[5].kind, ArtifactKind::Transient);
  for (const auto& f : flags) {
    EXPECT_FALSE(f.triggered) << toString(f.kind) << ": " << f.evidence;
    EXPECT_FALSE(f.evidence.empty()) << toString(f.kind);
  }
  EXPECT_STREQ(toString(ArtifactKind::ChargeLeakage), "charge_leakage");
  ctx.timesS.clear();
  EXPECT_THROW((void)checkEdge(ctx, {}, ArtifactParams{}), InputError);
}

TEST(Artifacts, ContextFromThePreprocessingSidecar) {
  const nlohmann::json prepared = {
      {"width_px", 128},
      {"height_px", 96},
      {"psf", {{"fwhm_px", 2.5}}},
      {"sky_rate_px_s", {{"vx", 0.25}, {"vy", -0.1}}},
      {"stars",
       {{{"x_px", 81.8}, {"y_px", 34.6}, {"snr", 12662.0}, {"saturated", true}, {"bleed_columns", {81, 82}}},
        {{"x_px", 10.0}, {"y_px", 20.0}, {"snr", 30.0}}}}};
  const std::vector<double> mjd = {60000.0, 60000.0 + 1.0 / 86400.0, 60000.0 + 2.0 / 86400.0};
  const ArtifactContext ctx = artifactContextFromPrepared(prepared, mjd, "prepared.json");
  EXPECT_EQ(ctx.width, 128);
  EXPECT_EQ(ctx.height, 96);
  EXPECT_DOUBLE_EQ(ctx.psfFwhmPx, 2.5);
  EXPECT_DOUBLE_EQ(ctx.skyRate.vy, -0.1);
  ASSERT_EQ(ctx.stars.size(), 2u);
  EXPECT_TRUE(ctx.stars[0].saturated);
  EXPECT_EQ(ctx.stars[0].bleedColumns, (std::vector<int>{81, 82}));
  EXPECT_FALSE(ctx.stars[1].saturated);
  ASSERT_EQ(ctx.timesS.size(), 3u);
  EXPECT_NEAR(ctx.timesS[0], -1.0, 1e-6);  // MJD 6e4 carries ~1e-11 day of rounding
  EXPECT_NEAR(ctx.timesS[2], 1.0, 1e-6);
  EXPECT_TRUE(checkChargeLeakage(ctx, {82.0, 60.0, {0.25, 1.0}}, ArtifactParams{}).triggered);
  nlohmann::json broken = prepared;
  broken.erase("psf");
  try {
    (void)artifactContextFromPrepared(broken, mjd, "prepared.json");
    FAIL() << "no error for a sidecar without psf";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("prepared.json"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("psf"), std::string::npos) << e.what();
  }
  EXPECT_THROW((void)artifactContextFromPrepared(prepared, {}, "prepared.json"), InputError);
  // Frames that do not match the times are refused rather than read out of range.
  ArtifactContext bad = baseContext();
  FrameCube three(16, 16, 3);
  bad.frames = &three;
  EXPECT_THROW((void)checkTransient(bad, {8.0, 8.0, {}}, ArtifactParams{}, nullptr), InputError);
  EXPECT_EQ(toJson(ArtifactParams{})["spike_angles_deg"], nlohmann::json({0.0, 90.0}));
}

}  // namespace
}  // namespace st::vet

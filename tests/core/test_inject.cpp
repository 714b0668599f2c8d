// Injection-recovery (core/inject): synthetic movers injected into a simulated raw cube ("small" preset,
// 128 x 128 x 64, conventional CCD with gain 2, stars, a saturated star, cosmic rays, hot pixels) with known
// noise. Oracles: (a) the calibrated difference frames hold the requested flux (within 2% with Poisson
// noise at SNR 80-100, 0.5% without); (b) the expected SNR against the analytic value for uniform noise and a stationary
// Moffat, a Monte Carlo of the matched-filter statistic (mean / scatter), and the local noise against the
// simulator's; (c) movers stay inside the frame, away from masked stars over the whole span; (d) recovery on
// a hand-made truth and candidates pair gives exact counts; (e) the completeness SVG is well-formed XML.
#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <random>

#include "st/calib/calibration.hpp"
#include "st/common/error.hpp"
#include "st/inject/completeness_svg.hpp"
#include "st/inject/injection.hpp"
#include "st/inject/recovery.hpp"
#include "st/inject/truth_json.hpp"
#include "st/io/fits_copy.hpp"
#include "st/io/fits_reader.hpp"
#include "st/io/fits_writer.hpp"
#include "st/sim/simulator.hpp"
#include "inject_fixture.hpp"
#include "test_support.hpp"

namespace st::inject {
namespace {

using fixture::calibratedCopy;
using fixture::makeSimField;
using fixture::SimField;
using fixture::smallParams;

/// Sum of `image` (calibrated frame n of the difference) over the pixels of `s` inside the frame.
double sumOver(const FrameCube& diff, std::size_t n, const Stamp& s) {
  double sum = 0.0;
  for (int y = std::max(0, s.y0); y < std::min(diff.height(), s.y0 + s.height); ++y)
    for (int x = std::max(0, s.x0); x < std::min(diff.width(), s.x0 + s.width); ++x)
      sum += diff.frame(n)[static_cast<std::size_t>(y) * diff.width() + x];
  return sum;
}

FrameCube difference(const FrameCube& a, const FrameCube& b) {
  FrameCube d = a;
  for (std::size_t i = 0; i < d.pixels().size(); ++i)
    d.pixels()[i] = a.pixels()[i] - b.pixels()[i];
  return d;
}

// (a) The calibrated difference holds the requested flux: per mover (mean over frames of the sum over its
// stamp) and over whole frames. Poisson noise at the simulator's gain of 2 e-/ADU: ~0.3% scatter here.
TEST(Inject, CalibratedDifferenceHoldsTheRequestedFlux) {
  const SimField s = makeSimField(3);
  CancelToken c;
  InjectParams params = smallParams(5);
  params.snrMin = 80.0;  // bright enough that the injected Poisson noise (~0.6% of the flux) leaves 2% free
  params.snrMax = 100.0;
  const InjectionPlan plan = planInjection(s.calibrated, s.field, params, c);
  ASSERT_EQ(plan.objects.size(), 4u);
  for (const double gain : {s.sim.truth.gainEPerAdu, 0.0}) {
    RawGeometry g = rawGeometry(s.sim.cube, s.masters, {});
    g.gainEPerAdu = gain;
    EXPECT_FALSE(g.flat.empty()) << "the simulator's flat must be applied in raw counts";
    FrameCube injected = s.sim.cube;
    addToCube(injected, plan, g);
    const FrameCube diff = difference(calibratedCopy(injected, s.masters), s.calibrated);
    const double tol = gain > 0.0 ? 0.02 : 0.005;
    double expectedTotal = 0.0;
    for (const auto& o : plan.objects) {
      double sum = 0.0;
      for (std::size_t n = 0; n < diff.frameCount(); ++n)
        sum += sumOver(diff, n, o.stamps[n]);
      const double perFrame = sum / static_cast<double>(diff.frameCount());
      EXPECT_NEAR(perFrame / o.flux, 1.0, tol) << "mover " << o.id << " gain " << gain;
      expectedTotal += o.flux;
    }
    const double total = std::accumulate(diff.pixels().begin(), diff.pixels().end(), 0.0) / diff.frameCount();
    EXPECT_NEAR(total / expectedTotal, 1.0, tol) << "gain " << gain;
  }
}

// (b) Uniform noise, a stationary Moffat of FWHM 6 px: sum P^2 -> (beta - 1)^2 / (pi R^2 (2 beta - 1)) per
// frame for the unit-flux profile (pixel integration and the 1e-3 truncation change it by < 1%).
TEST(Inject, ExpectedSnrMatchesTheAnalyticValueForUniformNoise) {
  const psf::Moffat m = psf::Moffat::fromFwhm(6.0, 4.0);
  const double sigma = 3.0;
  const int frames = 10;
  std::vector<Stamp> stamps(frames, trailedStamp(m, 40.3, 40.7, 40.3, 40.7, stampRadiusPx(m)));
  const double info = trackInformation(stamps, std::vector<double>(frames, sigma));
  const double analytic = frames * std::pow(m.beta - 1, 2) / (M_PI * m.radius * m.radius * (2 * m.beta - 1)) /
                          (sigma * sigma);
  std::printf("information %.6g, analytic %.6g (ratio %.4f)\n", info, analytic, info / analytic);
  EXPECT_NEAR(info / analytic, 1.0, 0.03);
  EXPECT_NEAR(stamps.front().sum(), 1.0, 1e-12);
  const double flux = fluxForSnr(10.0, info);
  EXPECT_NEAR(flux * std::sqrt(info), 10.0, 1e-9);
}

// (b) Monte Carlo: a trailed mover in Gaussian noise of a different sigma in each frame; the optimal
// matched-filter statistic at the true track, over 10000 noise draws, has mean / standard deviation equal
// to the expected SNR (its sampling error ~0.7% here), mean = the expected SNR and unit scatter.
TEST(Inject, ExpectedSnrMatchesAMonteCarloOfTheMatchedFilter) {
  const psf::Moffat m{2.0, 4.0};
  const int frames = 12;
  std::vector<Stamp> stamps;
  std::vector<double> sigma;
  for (int n = 0; n < frames; ++n) {
    const double x = 30.0 + 0.37 * n, y = 25.0 - 0.21 * n;  // trails of 0.6 x 0.4 px
    stamps.push_back(trailedStamp(m, x - 0.3, y + 0.2, x + 0.3, y - 0.2, stampRadiusPx(m)));
    sigma.push_back(2.0 + 0.25 * n);
  }
  const double info = trackInformation(stamps, sigma);
  const double expectedSnr = 8.0;
  const double flux = fluxForSnr(expectedSnr, info);
  std::mt19937_64 rng(42);
  std::normal_distribution<double> normal(0.0, 1.0);
  const int trials = 10000;
  double sum = 0.0, sum2 = 0.0;
  for (int t = 0; t < trials; ++t) {
    double psi = 0.0;
    for (int n = 0; n < frames; ++n)
      for (const double p : stamps[n].values) {
        const double d = flux * p + sigma[n] * normal(rng);
        psi += p * d / (sigma[n] * sigma[n]);
      }
    const double s = psi / std::sqrt(info);
    sum += s;
    sum2 += s * s;
  }
  const double mean = sum / trials, sd = std::sqrt(sum2 / trials - mean * mean);
  std::printf("Monte Carlo: mean %.4f, sd %.4f, mean/sd %.4f (expected SNR %.1f)\n", mean, sd, mean / sd,
              expectedSnr);
  EXPECT_NEAR(mean / sd / expectedSnr, 1.0, 0.03);
  EXPECT_NEAR(mean / expectedSnr, 1.0, 0.03);
  EXPECT_NEAR(sd, 1.0, 0.03);
}

// (b) The local noise is the pixel noise: frame-to-frame sky offsets and a static gradient are not noise.
TEST(Inject, LocalFrameNoiseIgnoresSkyOffsetsAndStaticStructure) {
  const int w = 60, h = 60, frames = 15;
  FrameCube cube(w, h, frames);
  std::mt19937_64 rng(7);
  std::normal_distribution<double> normal(0.0, 1.0);
  for (int n = 0; n < frames; ++n) {
    cube.info()[n].mjdMid = 60000.0 + n * 300.0 / 86400.0;
    cube.info()[n].exposureS = 300.0;
    const double offset = 50.0 * std::sin(1.3 * n), sigma = n == 7 ? 8.0 : 4.0;
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x)
        cube.frame(n)[y * w + x] = static_cast<float>(1000.0 + offset + 2.0 * x + sigma * normal(rng));
  }
  EXPECT_NEAR(residualScale(15), 0.93, 0.01) << "residuals about a 15-frame median are ~7% small";
  EXPECT_NEAR(residualScale(1000), 1.0, 0.01);
  const std::vector<double> s = localFrameNoise(cube, {}, {0, 0, w, h});
  double mean = 0.0;
  for (int n = 0; n < frames; ++n) {
    if (n == 7) continue;
    EXPECT_NEAR(s[n] / 4.0, 1.0, 0.06) << "frame " << n;
    mean += s[n] / (frames - 1);
  }
  EXPECT_NEAR(mean / 4.0, 1.0, 0.02);
  EXPECT_NEAR(s[7] / 8.0, 1.0, 0.1) << "a noisier frame is seen as noisier";
  EXPECT_THROW(localFrameNoise(cube, {}, {0, 0, 5, 5}), InputError);
}

// (b) On the simulated cube, the noise recorded for each mover is the simulator's per-frame sigma.
TEST(Inject, MoverNoiseIsTheSimulatorsNoise) {
  const SimField s = makeSimField(3);
  CancelToken c;
  const InjectionPlan plan = planInjection(s.calibrated, s.field, smallParams(9), c);
  for (const auto& o : plan.objects) {
    double ratio = 0.0;
    for (std::size_t n = 0; n < o.frameNoise.size(); ++n)
      ratio += o.frameNoise[n] / s.sim.truth.noiseSigmaAdu[n] / o.frameNoise.size();
    EXPECT_NEAR(ratio, 1.0, 0.05) << "mover " << o.id;
  }
}

// (c) Inside the frame by the margin and away from the mask over the whole span, in every frame; the
// mask covers the simulated stars bright enough to matter; the same seed gives the same plan.
TEST(Inject, MoversStayInsideTheFrameAndAwayFromStars) {
  const SimField s = makeSimField(3, true);
  EXPECT_TRUE(s.field.psfMeasured);
  EXPECT_NEAR(s.field.psf.fwhm() / s.sim.truth.psfFwhmPx, 1.0, 0.15) << "PSF fitted on the frames' stars";
  CancelToken c;
  const InjectionPlan plan = planInjection(s.calibrated, s.field, smallParams(11, 6), c);
  ASSERT_EQ(plan.objects.size(), 6u);
  const double margin = plan.params.edgeMarginPx, away = plan.params.minStarDistancePx;
  EXPECT_GE(away, 3.0 * s.field.psf.fwhm() - 1e-9);
  for (const auto& o : plan.objects)
    for (std::size_t n = 0; n < plan.tOffsetS.size(); ++n)
      for (const double f : {-0.5, 0.0, 0.5}) {
        const double t = plan.tOffsetS[n] + f * plan.exposureS[n];
        const double x = o.xPx + o.vxPxS * t, y = o.yPx + o.vyPxS * t;
        ASSERT_GE(x, margin);
        ASSERT_GE(y, margin);
        ASSERT_LE(x, plan.width - 1 - margin);
        ASSERT_LE(y, plan.height - 1 - margin);
        const auto i = static_cast<std::size_t>(std::lround(y)) * plan.width + std::lround(x);
        EXPECT_GE(s.field.maskDistancePx[i], away) << "mover " << o.id << " frame " << n;
        for (const auto& star : s.sim.truth.stars) {
          if (star.photonsPerFrame < 2000.0) continue;  // faint stars: below the median frame's 5 sigma
          EXPECT_GE(std::hypot(x - star.xRefPx, y - star.yRefPx), away) << "mover " << o.id;
        }
      }
  int bright = 0;
  for (const auto& star : s.sim.truth.stars) {
    const auto ix = std::lround(star.xRefPx), iy = std::lround(star.yRefPx);
    if (star.photonsPerFrame < 2000.0 || ix < 0 || iy < 0 || ix >= plan.width || iy >= plan.height) continue;
    ++bright;
    EXPECT_EQ(s.field.mask[static_cast<std::size_t>(iy) * plan.width + ix], 1) << "star at " << ix << "," << iy;
  }
  EXPECT_GE(bright, 1);
  const InjectionPlan again = planInjection(s.calibrated, s.field, smallParams(11, 6), c);
  EXPECT_EQ(again.objects.front().xPx, plan.objects.front().xPx);
  EXPECT_NE(planInjection(s.calibrated, s.field, smallParams(12, 6), c).objects.front().xPx,
            plan.objects.front().xPx);
  EXPECT_THROW(planInjection(s.calibrated, s.field, smallParams(11, 500), c), InputError);
}

// The truth file reads back; names of the copies.
TEST(Inject, TruthJsonRoundTripAndFileNames) {
  const SimField s = makeSimField(3);
  CancelToken c;
  InjectionRun run;
  run.plan = planInjection(s.calibrated, s.field, smallParams(5), c);
  run.field = s.field;
  TruthMeta meta;
  const nlohmann::json j = truthToJson(run, meta);
  EXPECT_TRUE(j["objects"][0]["magnitude"].is_null());
  EXPECT_TRUE(j["plate_scale_arcsec_px"].is_null());
  const Truth t = truthFromJson(j);
  ASSERT_EQ(t.objects.size(), run.plan.objects.size());
  EXPECT_EQ(*t.tRefMjd, run.plan.tRefMjd);
  EXPECT_EQ(t.objects[2].xPx, run.plan.objects[2].xPx);
  EXPECT_EQ(t.objects[2].expectedSnr, run.plan.objects[2].expectedSnr);
  EXPECT_THROW(truthFromJson(nlohmann::json{{"objects", {{{"id", 1}}}}}), InputError);
  EXPECT_EQ(injectedFileName("/a/b/20190326.0131.fits.fz"), "20190326.0131.fits");
  EXPECT_EQ(injectedFileName("x.fits.gz"), "x.fits");
  EXPECT_EQ(injectedFileName("frame.fit"), "frame.fit");
  EXPECT_EQ(injectedFileName("frame.fz"), "frame.fits");
}

// The FITS copy adds the image to the plane and keeps the header, with STINJECT and HISTORY added.
TEST(Inject, FitsCopyAddsPixelsAndKeepsTheHeader) {
  test::TempDir dir;
  Image img(20, 10, 100.0f);
  FitsHeader h;
  h.setNumber("EXPTIME", 30.0);
  h.setString("DATE-OBS", "2020-01-02T03:04:05");
  h.setString("OBJECT", "field 7");
  io::writeImage((dir / "in.fits").string(), img, h);
  Image add(20, 10, 0.0f);
  add.at(3, 4) = 12.5f;
  FitsHeader cards;
  cards.set("STINJECT", "2", "test");
  const io::CopyReport r = io::copyWithAddedPixels((dir / "in.fits").string(), (dir / "out.fits").string(),
                                                   {{1, 0, &add}}, cards, {"injected"});
  EXPECT_EQ(r.clippedPixels, 0u);
  const FrameCube out = io::loadFrames({(dir / "out.fits").string()});
  EXPECT_FLOAT_EQ(out.frame(0)[4 * 20 + 3], 112.5f);
  EXPECT_FLOAT_EQ(out.frame(0)[0], 100.0f);
  EXPECT_EQ(out.header.getString("OBJECT").value_or(""), "field 7");
  EXPECT_EQ(out.header.getDouble("STINJECT").value_or(0), 2.0);
  EXPECT_EQ(out.info()[0].exposureS, 30.0);
  Image wrong(5, 5);
  EXPECT_THROW(io::copyWithAddedPixels((dir / "in.fits").string(), (dir / "bad.fits").string(), {{1, 0, &wrong}}),
               InputError)
      << "a size mismatch is refused";
  EXPECT_THROW(io::copyWithAddedPixels((dir / "in.fits").string(), (dir / "bad.fits").string(), {{3, 0, &add}}),
               InputError)
      << "a missing HDU is refused";
}

// (d) Hand-made truth and candidates with known outcomes: 8 movers; 5 found (one at 1.9 px, one found by
// two candidates), one candidate 2.1 px away, one 1.5 grid steps off in vx, one false alarm.
TEST(Recovery, HandMadePairGivesExactCounts) {
  Truth truth;
  truth.tRefMjd = 60000.0;
  const double snrs[] = {5.0, 5.5, 7.0, 9.0, 11.0, 13.0, 18.0, 25.0};
  for (int i = 0; i < 8; ++i)
    truth.objects.push_back({i + 1, 100.0 + 50.0 * i, 200.0, 0.01, -0.02, 100.0, snrs[i], 20.0 + 0.3 * i});
  CandidateSet cands;
  cands.gridStepPxS = 0.001;
  cands.tRefMjd = 60000.0 - 100.0 / 86400.0;  // the search's t_ref is 100 s earlier: positions move by v*100
  auto cand = [&](double x, double y, double vx, double vy, double snr) {
    const int index = static_cast<int>(cands.candidates.size());
    cands.candidates.push_back({index, x - vx * 100.0, y - vy * 100.0, vx, vy, snr, {}});
  };
  cand(100.0, 200.0, 0.01, -0.02, 4.0);           // 0: mover 1 (SNR 5)
  cand(151.9, 200.0, 0.0105, -0.02, 6.0);         // 1: mover 2 at 1.9 px
  cand(202.1, 200.0, 0.01, -0.02, 7.0);           // 2: 2.1 px from mover 3: unmatched
  cand(250.0, 200.0, 0.0115, -0.02, 8.0);         // 3: 1.5 steps off in vx from mover 4: unmatched
  cand(300.5, 200.0, 0.01, -0.0195, 9.9);         // 4: mover 5 (SNR 11)
  cand(300.0, 200.7, 0.01, -0.02, 9.0);           // 5: mover 5 again, farther: a duplicate
  cand(450.0, 200.0, 0.01, -0.02, 30.0);          // 6: mover 8 (SNR 25)
  cand(400.0, 201.0, 0.0108, -0.0191, 15.0);      // 7: mover 7 (SNR 18)
  cand(800.0, 800.0, 0.0, 0.0, 7.5);              // 8: a false alarm
  const RecoveryResult r = matchRecovery(truth, cands, {});
  EXPECT_NEAR(r.timeShiftS, 100.0, 1e-5);
  EXPECT_EQ(r.total, 8);
  EXPECT_EQ(r.recovered, 5);
  const std::vector<int> candidateOf = {0, 1, -1, -1, 4, -1, 7, 6};
  for (int i = 0; i < 8; ++i)
    EXPECT_EQ(r.objects[i].candidate, candidateOf[i]) << "mover " << i + 1;
  // Bins 4-6 (movers 1, 2: both), 6-8 (3: missed), 8-10 (4: missed), 10-12 (5: found), 12-16 (6: missed),
  // 16-20 (7: found), >=20 (8: found).
  ASSERT_EQ(r.snrBins.size(), 7u);
  const int total[] = {2, 1, 1, 1, 1, 1, 1}, found[] = {2, 0, 0, 1, 0, 1, 1};
  for (int b = 0; b < 7; ++b) {
    EXPECT_EQ(r.snrBins[b].total, total[b]) << r.snrBins[b].label;
    EXPECT_EQ(r.snrBins[b].recovered, found[b]) << r.snrBins[b].label;
  }
  EXPECT_EQ(r.snrBins.front().label, "4-6");
  EXPECT_EQ(r.snrBins.back().label, ">=20");
  EXPECT_FALSE(r.magBins.empty());
  int magTotal = 0;
  for (const auto& b : r.magBins)
    magTotal += b.total;
  EXPECT_EQ(magTotal, 8);
  // SNR ratios 4/5, 6/5.5, 9.9/11, 15/18, 30/25: median 0.9.
  ASSERT_TRUE(r.medianSnrRatio.has_value());
  EXPECT_NEAR(*r.medianSnrRatio, 0.9, 1e-12);
  ASSERT_EQ(r.unmatched.size(), 4u);
  EXPECT_EQ(r.unmatched[0].candidate.index, 2);
  EXPECT_FALSE(r.unmatched[0].duplicate);
  EXPECT_EQ(r.unmatched[0].nearestId, 3);
  EXPECT_NEAR(r.unmatched[0].nearestDistancePx, 2.1, 1e-6);
  EXPECT_EQ(r.unmatched[2].candidate.index, 5);
  EXPECT_TRUE(r.unmatched[2].duplicate);
  EXPECT_EQ(r.unmatched[3].candidate.snr, 7.5);
  // A wider tolerance takes the 2.1 px and the 1.5-step candidates too.
  RecoveryParams wide;
  wide.matchPx = 2.5;
  wide.matchVSteps = 2.0;
  EXPECT_EQ(matchRecovery(truth, cands, wide).recovered, 7);
  // Two runs scored together: the counts add up, bins included.
  const RecoveryResult both = combineRecovery({r, r}, {});
  EXPECT_EQ(both.total, 16);
  EXPECT_EQ(both.recovered, 10);
  EXPECT_EQ(both.snrBins.front().total, 4);
  EXPECT_EQ(both.unmatched.size(), 8u);
  EXPECT_EQ(both.objects.back().set, 1);
  EXPECT_NEAR(*both.medianSnrRatio, 0.9, 1e-12);
  // Without a grid step or a tolerance there is no velocity criterion.
  CandidateSet noStep = cands;
  noStep.gridStepPxS.reset();
  EXPECT_THROW(matchRecovery(truth, noStep, {}), InputError);
}

TEST(Recovery, WilsonIntervalAndBins) {
  const auto [lo, hi] = wilsonInterval(5, 10);
  EXPECT_NEAR(lo, 0.5 - 0.15076, 1e-4);
  EXPECT_NEAR(hi, 0.5 + 0.15076, 1e-4);
  EXPECT_EQ(wilsonInterval(0, 0), std::make_pair(0.0, 1.0));
  EXPECT_DOUBLE_EQ(wilsonInterval(0, 10).first, 0.0);
  EXPECT_GT(wilsonInterval(0, 10).second, 0.05);
  EXPECT_DOUBLE_EQ(wilsonInterval(10, 10).second, 1.0);
  const auto bins = completenessBins({3.0, 4.0, 25.0}, {true, false, true}, {4, 6});
  ASSERT_EQ(bins.size(), 3u);
  EXPECT_EQ(bins[0].label, "<4");
  EXPECT_EQ(bins[0].recovered, 1);
  EXPECT_EQ(bins[1].total, 1);
  EXPECT_EQ(bins[2].total, 1);
  EXPECT_THROW(completenessBins({1.0}, {true}, {6, 4}), InputError);
}

TEST(Recovery, ReadsTheSearchJson) {
  const nlohmann::json j = {
      {"t_ref_mjd", 60000.5},
      {"grid", {{"step_px_s", 0.002}, {"nvx", 3}}},
      {"candidates",
       {{{"x", 10}, {"y", 12}, {"vx_px_s", 0.1}, {"vy_px_s", -0.2}, {"snr", 7.5}, {"flags", {"partial"}}}}}};
  const CandidateSet c = candidatesFromJson(j);
  ASSERT_EQ(c.candidates.size(), 1u);
  EXPECT_EQ(*c.gridStepPxS, 0.002);
  EXPECT_EQ(*c.tRefMjd, 60000.5);
  EXPECT_EQ(c.candidates[0].flags.at(0), "partial");
  EXPECT_THROW(candidatesFromJson(nlohmann::json{{"candidates", {{{"x", 1}}}}}), InputError);
  EXPECT_EQ(candidatesFromJson(nlohmann::json::array()).candidates.size(), 0u);
}

// A mover that the search set aside as static (moving less than one FWHM over the span) is not recovered and
// not an unmatched candidate; recovery names it apart, in the summary, the text and the JSON.
TEST(Recovery, MoversSetAsideAsStaticAreCountedApart) {
  Truth truth;
  truth.objects.push_back({1, 100.0, 100.0, 0.001, 0.0, 100.0, 9.0, {}});
  truth.objects.push_back({2, 300.0, 100.0, 0.001, 0.0, 100.0, 12.0, {}});
  truth.objects.push_back({3, 500.0, 100.0, 0.001, 0.0, 100.0, 15.0, {}});
  const nlohmann::json j = {
      {"grid", {{"step_px_s", 0.002}}},
      {"candidates", {{{"x", 300.4}, {"y", 100}, {"vx_px_s", 0.0}, {"vy_px_s", 0.0}, {"snr", 11.0}}}},
      {"static_sources",
       {{{"x", 900}, {"y", 900}, {"vx_px_s", 0.0}, {"vy_px_s", 0.0}, {"snr", 40.0}},   // a star
        {{"x", 100.5}, {"y", 99.5}, {"vx_px_s", 0.0}, {"vy_px_s", 0.0}, {"snr", 8.0}},  // mover 1
        {{"x", 300}, {"y", 100}, {"vx_px_s", 0.0}, {"vy_px_s", 0.0}, {"snr", 10.0}}}}}; // mover 2, also a mover
  const CandidateSet c = candidatesFromJson(j);
  ASSERT_EQ(c.staticSources.size(), 3u);
  EXPECT_EQ(c.staticSources[1].snr, 8.0);
  const RecoveryResult r = matchRecovery(truth, c, {});
  EXPECT_EQ(r.recovered, 1);
  EXPECT_EQ(r.setAsideStatic, 1);
  EXPECT_EQ(r.objects[0].staticSource, 1);
  EXPECT_EQ(r.objects[0].staticSnr, 8.0);
  EXPECT_FALSE(r.objects[0].recovered());
  EXPECT_EQ(r.objects[1].candidate, 0);
  EXPECT_FALSE(r.objects[1].setAsideStatic()) << "recovered as a mover: not also static";
  EXPECT_FALSE(r.objects[2].recovered() || r.objects[2].setAsideStatic());
  EXPECT_TRUE(r.unmatched.empty()) << "static sources are never unmatched candidates";
  EXPECT_NE(recoveryText(r).find("1 more found but set aside as static"), std::string::npos);
  const nlohmann::json out = recoveryToJson(r);
  EXPECT_EQ(out["summary"]["set_aside_static"], 1);
  EXPECT_EQ(out["objects"][0]["static_source"], 1);
  EXPECT_FALSE(out["objects"][2].contains("static_source"));
  EXPECT_EQ(combineRecovery({r, r}, {}).setAsideStatic, 2);
  EXPECT_THROW(candidatesFromJson(nlohmann::json{{"candidates", nlohmann::json::array()}, {"static_sources", 3}}),
               InputError);
}

// The files of `recovery --out DIR` (the CLI and the GUI write them through this one function).
TEST(Recovery, WritesItsFilesOrNamesThePathItCannotMake) {
  Truth truth;
  truth.objects.push_back({1, 10.0, 10.0, 0.0, 0.0, 100.0, 12.0, {}});
  CandidateSet c;
  c.gridStepPxS = 0.01;
  c.candidates.push_back({0, 10.2, 10.0, 0.0, 0.0, 11.0, {}});
  const RecoveryResult r = matchRecovery(truth, c, {});
  const auto dir = std::filesystem::temp_directory_path() / "st_recovery_outputs_test" / "out";
  std::filesystem::remove_all(dir.parent_path());
  writeRecoveryOutputs(r, nlohmann::json::array({{{"set", 0}}}), dir.string());
  for (const char* f : {"recovery.json", "completeness.csv", "objects.csv", "unmatched.csv", "completeness.svg"})
    EXPECT_TRUE(std::filesystem::exists(dir / f)) << f;
  std::ifstream in(dir / "recovery.json");
  const nlohmann::json j = nlohmann::json::parse(in);
  EXPECT_EQ(j["summary"]["recovered"], 1);
  EXPECT_EQ(j["sets"].size(), 1u);
  EXPECT_EQ(recoveryPlotTitle(r), "Injection-recovery: 1 of 1 movers recovered");
  // A folder below a plain file cannot be made: an InputError naming it (not a filesystem_error).
  const auto blocker = dir / "recovery.json" / "sub";
  try {
    writeRecoveryOutputs(r, nlohmann::json::array(), blocker.string());
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(blocker.string()), std::string::npos) << e.what();
  }
  std::filesystem::remove_all(dir.parent_path());
}

/// True when the '&' at `at` of `s` starts one of XML's five entities.
bool entityAt(const std::string& s, std::size_t at) {
  for (const std::string e : {"&amp;", "&lt;", "&gt;", "&quot;", "&apos;"})
    if (s.compare(at, e.size(), e) == 0) return true;
  return false;
}

/// A small XML well-formedness check: one root, every tag closed in order, attributes name="value",
/// no '<' or bare '&' in text or attribute values.
std::string xmlProblem(const std::string& s) {
  std::vector<std::string> stack;
  std::size_t i = 0;
  int roots = 0;
  auto entityOk = [&](std::size_t at) { return entityAt(s, at); };
  while (i < s.size()) {
    if (s[i] != '<') {
      if (s[i] == '&' && !entityOk(i)) return "bare & at " + std::to_string(i);
      if (s[i] == '>') return "bare > at " + std::to_string(i);
      if (stack.empty() && !std::isspace(static_cast<unsigned char>(s[i]))) return "text outside the root";
      ++i;
      continue;
    }
    if (s.compare(i, 5, "<?xml") == 0) {
      const auto e = s.find("?>", i);
      if (e == std::string::npos || i != 0) return "bad XML declaration";
      i = e + 2;
      continue;
    }
    const auto end = s.find('>', i);
    if (end == std::string::npos) return "unclosed tag at " + std::to_string(i);
    std::string tag = s.substr(i + 1, end - i - 1);
    i = end + 1;
    if (tag.empty()) return "empty tag";
    if (tag[0] == '/') {
      if (stack.empty() || stack.back() != tag.substr(1)) return "mismatched </" + tag.substr(1) + ">";
      stack.pop_back();
      continue;
    }
    const bool selfClosing = tag.back() == '/';
    if (selfClosing) tag.pop_back();
    std::size_t k = 0;
    while (k < tag.size() && !std::isspace(static_cast<unsigned char>(tag[k])))
      ++k;
    const std::string name = tag.substr(0, k);
    if (name.empty() || !std::isalpha(static_cast<unsigned char>(name[0]))) return "bad tag name '" + name + "'";
    while (k < tag.size()) {  // attributes
      while (k < tag.size() && std::isspace(static_cast<unsigned char>(tag[k])))
        ++k;
      if (k == tag.size()) break;
      const auto eq = tag.find('=', k);
      if (eq == std::string::npos || tag[eq + 1] != '"') return "bad attribute in <" + name + ">";
      const auto close = tag.find('"', eq + 2);
      if (close == std::string::npos) return "unclosed attribute in <" + name + ">";
      const std::string value = tag.substr(eq + 2, close - eq - 2);
      if (value.find('<') != std::string::npos) return "'<' in an attribute of <" + name + ">";
      for (std::size_t a = 0; a < value.size(); ++a)
        if (value[a] == '&' && !entityAt(value, a)) return "bare & in an attribute of <" + name + ">";
      k = close + 1;
    }
    if (stack.empty()) ++roots;
    if (!selfClosing) stack.push_back(name);
  }
  if (!stack.empty()) return "unclosed <" + stack.back() + ">";
  if (roots != 1) return std::to_string(roots) + " root elements";
  return {};
}

// (e) The completeness plot is well-formed XML (SVG root, escaped title), with one point per non-empty bin
// and labelled axes.
TEST(Recovery, CompletenessSvgIsWellFormed) {
  const auto bins = completenessBins({4.5, 5.0, 7.0, 11.0, 30.0}, {false, true, false, true, true},
                                     {4, 6, 8, 10, 12, 16, 20});
  const std::string svg = completenessSvg(bins, "A <title> & \"quotes\"");
  EXPECT_EQ(xmlProblem(svg), "");
  EXPECT_NE(svg.find("<svg xmlns=\"http://www.w3.org/2000/svg\""), std::string::npos);
  EXPECT_NE(svg.find("A &lt;title&gt; &amp; &quot;quotes&quot;"), std::string::npos);
  EXPECT_NE(svg.find("expected SNR"), std::string::npos);
  EXPECT_NE(svg.find("completeness (fraction recovered)"), std::string::npos);
  std::size_t circles = 0;
  for (auto p = svg.find("<circle"); p != std::string::npos; p = svg.find("<circle", p + 1))
    ++circles;
  EXPECT_EQ(circles, 4u) << "bins 4-6, 6-8, 10-12 and >=20 hold objects";
  EXPECT_NE(xmlProblem("<svg><g></svg></g>"), "") << "the checker must catch misnested tags";
  EXPECT_NE(xmlProblem("<svg a=\"1 & 2\"/>"), "") << "the checker must catch a bare &";
}

}  // namespace
}  // namespace st::inject

// The demo's pipeline over 20 seeds of the paper's observation that are not the demo's (issue 14): simulate
// paper-neo (500 frames of 512^2, EMCCD, stars drifting 16.4 px/s, one V = 23.1 asteroid of expected SNR
// ~15), pre-process with the defaults, search as the demo does (+-8 deg/day, 1.5 px steps over the span,
// method auto). Issue 14 asks, over the 20 seeds: the asteroid found in all (2 px, one grid step), SNR within
// 5% on average and 15% in each, other candidates at most 2 x Prob_false + 1 (static sources at the sky rate,
// which the search sets aside, are listed but not counted). The stars drift 16.4 px/s and
// the asteroid only 0.7 px/s relative to them, so its track runs through stars' footprints for hundreds of
// frames: masking every star down to one stack sigma lost seed 24 and put 3 more at the wrong velocity;
// pre-processing now subtracts the stars (a sky-registered template) and masks only their cores and the sky
// positions whose residuals vary more than the background. Also, on every seed: the pipeline's sky rate
// within 0.01 px/s of the simulator's drift (the many-seed claim of test_detect_sky_rate_slow.cpp, moved
// here on 2026-12-03 so that CI simulates each seed once; there the chained refinement alone). Figures at
// the end of the test. ~10 minutes on 2 idle cores (25 beside a build), 3.3 minutes on 16.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include "st/candidate/candidate_fit.hpp"
#include "st/detect/registration.hpp"
#include "st/pipeline/demo_search.hpp"
#include "st/pipeline/preprocess.hpp"
#include "st/search/cpu_backend.hpp"
#include "st/search/method_choice.hpp"
#include "st/search/velocity_grid.hpp"
#include "st/sim/simulator.hpp"
#include "st/stats/false_alarm.hpp"

namespace st::pipeline {
namespace {

TEST(PipelineSeeds, PaperNeoOverTwentySeeds) {
  NullProgress p;
  CancelToken c;
  const auto backend = search::makeCpuBackend();
  int found = 0, seeds = 0, others = 0, onVelocity = 0, oneStep = 0, within15 = 0, staticSet = 0;
  double sumRatio = 0.0, expectedFalse = 0.0, maxRateErr = 0.0;
  int perFrame = 0;
  // The asteroid's segment positions (candidate::fitCandidate, each segment's own fit) against the truth's
  // track at each segment's time, in units of their own errors: what the tracklet of a report is worth.
  std::vector<double> pulls;
  // The same per segment of a 4-segment tracklet (x, y): sums and sums of squares, and counts. Over seeds
  // 21-130 (2026-12-05) the first segment's x pulls averaged -0.39 (rms 1.43) against -0.16 / +0.03 / +0.02
  // for the others; seeds 131-170 gave -0.09 (rms 0.93), and 100 fresh seeds (131-230) with the background
  // removed exactly (frames minus their noise-free scene) -0.12 +- 0.11: those seeds' noise, not a bias.
  // Seeds 21-40 alone: -0.68 (rms 1.20, 19 seeds).
  double segSum[4][2] = {}, segSum2[4][2] = {};
  int segCount[4] = {};
  int positions = 0, segmentsCut = 0;
  // ST_SEEDS=FIRST-LAST runs another range (a campaign over more seeds; the bounds below are the 20 seeds').
  unsigned first = 21, last = 40;
  if (const char* range = std::getenv("ST_SEEDS")) std::sscanf(range, "%u-%u", &first, &last);
  for (unsigned seed = first; seed <= last; ++seed) {
    sim::SimResult sim = sim::simulate(sim::preset("paper-neo"), seed, p, c);
    const sim::TruthObject truth = sim.truth.objects.at(0);
    const Prepared prep = preprocess(std::move(sim.cube), PreprocessParams{}, p, c);
    // The sky rate the pipeline measured (the chained refinement, or the registered star field's) against
    // the simulator's drift: within 0.01 px/s (0.3 px over the span) on every seed, the oracle of
    // test_detect_sky_rate_slow.cpp, which measures the chained refinement alone on two seeds.
    ++seeds;
    maxRateErr = std::max({maxRateErr, std::fabs(prep.skyRate.vx - sim.truth.skyVxPxPerS),
                           std::fabs(prep.skyRate.vy - sim.truth.skyVyPxPerS)});
    EXPECT_NEAR(prep.skyRate.vx, sim.truth.skyVxPxPerS, 0.01) << "seed " << seed;  // fails on NaN too
    EXPECT_NEAR(prep.skyRate.vy, sim.truth.skyVyPxPerS, 0.01) << "seed " << seed;
    // The simulated field moves exactly linearly: per-frame registration here is false "pointings" (seed 37
    // before 2026-12-04: "3 pointings", rms 0.919 px, its neighbour links pulled towards 0 by the bias
    // columns; registration_links.cpp). The rate must be the chained refinement's, its blocks' departures
    // from the line measurement noise (< 0.3 px rms), as the sky-rate test asserts on its own two seeds.
    if (prep.registration.model == detect::Registration::Model::PerFrame) {
      ++perFrame;
      ADD_FAILURE() << "seed " << seed << ": registration took per-frame offsets: " << prep.registration.note;
    } else {
      EXPECT_TRUE(prep.skyRateMeasured) << "seed " << seed;
      EXPECT_TRUE(prep.skyRateMeasurement.chained) << "seed " << seed << ": " << prep.skyRateMeasurement.note;
      EXPECT_LT(prep.skyRateMeasurement.residualRmsPx, 0.3) << "seed " << seed;
    }
    const search::VelocityGrid grid =
        search::makeVelocityGrid(demoGridSpec(prep.frames.plateScaleArcsecPerPx), prep.filtered);
    const search::SearchResult r =
        search::searchWithMethod(*backend, prep.filtered, grid, demoSearchParams(), p, c);
    expectedFalse += stats::expectedFalseAlarms(r.snrThreshold, r.trials.total());
    for (const auto& st : r.staticSources) {
      ++staticSet;
      std::printf("seed %u: static source set aside (%d, %d) v (%.2f, %.2f) px/s SNR %.2f\n", seed, st.x,
                  st.y, st.v.vx, st.v.vy, st.snr);
    }
    const search::Candidate* hit = nullptr;
    for (const auto& cd : r.candidates) {
      // Detected: at the asteroid's place (2.5 px) and near its velocity (5 grid steps); "on its velocity"
      // within 2 steps, counted apart (a track partly under a star's mask is found at a neighbouring one).
      const double dvx = std::fabs(cd.v.vx - truth.vxPxPerS) / grid.stepPxS,
                   dvy = std::fabs(cd.v.vy - truth.vyPxPerS) / grid.stepPxS;
      const double d = std::hypot(cd.x - truth.xRefPx, cd.y - truth.yRefPx);
      const bool isObject = d <= 2.5 && dvx <= 5.0 + 1e-9 && dvy <= 5.0 + 1e-9;
      if (isObject && !hit) onVelocity += dvx <= 2.0 + 1e-9 && dvy <= 2.0 + 1e-9;
      // One grid step: the cell next to the one nearest the truth (which is within half a step of it).
      if (isObject && !hit) oneStep += dvx <= 1.5 + 1e-9 && dvy <= 1.5 + 1e-9;
      if (isObject && !hit) {
        hit = &cd;
        continue;
      }
      // The asteroid's own partial detections at other velocities are not false alarms.
      if (cd.snr >= 7.0 && d > 5.0) {
        ++others;
        std::printf("seed %u: other candidate (%d, %d) v (%.2f, %.2f) px/s SNR %.2f\n", seed, cd.x, cd.y,
                    cd.v.vx, cd.v.vy, cd.snr);
      }
    }
    std::printf("seed %u: sky rate (%.3f, %.3f) truth (%.3f, %.3f); PSF FWHM %.2f (truth %.2f); %s", seed,
                prep.skyRate.vx, prep.skyRate.vy, sim.truth.skyVxPxPerS, sim.truth.skyVyPxPerS,
                prep.psf.fwhm(), sim.truth.psfFwhmPx, hit ? "found" : "MISSED");
    if (hit) {
      ++found;
      const double ratio = hit->snr / truth.expectedSnr;
      sumRatio += ratio;
      std::printf(
          " at SNR %.2f of %.2f (%+.1f%%), v (%.3f, %.3f) of (%.3f, %.3f) px/s (%.1f, %.1f steps), method "
          "%s\n",
          hit->snr, truth.expectedSnr, 100 * (ratio - 1), hit->v.vx, hit->v.vy, truth.vxPxPerS,
          truth.vyPxPerS, (hit->v.vx - truth.vxPxPerS) / grid.stepPxS,
          (hit->v.vy - truth.vyPxPerS) / grid.stepPxS, std::string(r.method.name()).c_str());
      EXPECT_NEAR(ratio, 1.0, 0.45) << "seed " << seed;
      within15 += std::fabs(ratio - 1.0) <= 0.15;
      const candidate::FitSummary fit = candidate::fitCandidate(prep, *hit, c);
      EXPECT_TRUE(fit.converged()) << "seed " << seed << ": " << fit.message;
      if (fit.segments) {
        segmentsCut += fit.segments->positionSegments;
        std::printf("seed %u: segment positions (of %d)", seed, fit.segments->positionSegments);
        for (const auto& q : fit.segments->positions) {
          ++positions;
          const double px = (q.x - (truth.xRefPx + truth.vxPxPerS * q.tOffsetS)) / q.sigmaXPx;
          const double py = (q.y - (truth.yRefPx + truth.vyPxPerS * q.tOffsetS)) / q.sigmaYPx;
          pulls.insert(pulls.end(), {px, py});
          if (fit.segments->positionSegments == 4 && q.segment >= 1 && q.segment <= 4) {
            const int k = q.segment - 1;
            segSum[k][0] += px;
            segSum[k][1] += py;
            segSum2[k][0] += px * px;
            segSum2[k][1] += py * py;
            ++segCount[k];
          }
          std::printf(" [%d: SNR %.1f, sigma (%.2f, %.2f) px, pull (%+.2f, %+.2f)]", q.segment, q.snr,
                      q.sigmaXPx, q.sigmaYPx, px, py);
        }
        std::printf("\n");
      }
    } else {
      std::printf(" (expected SNR %.2f at (%.1f, %.1f))\n", truth.expectedSnr, truth.xRefPx, truth.yRefPx);
    }
  }
  const double mean = found > 0 ? sumRatio / found : 0.0;
  std::printf(
      "found %d of %d (%d within one grid step, %d within two); mean search/expected SNR %.3f, %d within "
      "15%%; %d other candidates at SNR >= 7 (Prob_false predicts %.3f); %d static source(s) at the sky rate "
      "set aside; sky rate within %.4f px/s of the truth on every seed; per-frame registration on %d "
      "seed(s)\n",
      found, seeds, oneStep, onVelocity, mean, within15, others, expectedFalse, staticSet, maxRateErr,
      perFrame);
  // Measured 2026-11-25 (16-core device machine, CPU): found 20 of 20, 19 within one step, 20 within two;
  // mean 0.996, 17 of 20 within 15% (seed 24 -38% and 28 -23%: their tracks cross bright stars' cores;
  // seed 21 +18%); 1 other candidate (an edge detection, SNR 7.08; issue 14's bound: 2 x 0.014 + 1) while
  // weak non-static sources were subtracted too; that was taken back (it zeroed a mover's pixels in
  // test_pipeline_residuals), which brings back seed 34's pair of faint stars at the sky rate (SNR 11.0): 2.
  // 2026-11-26 (H200 machine, CPU), registration on by default: the same figures (seed 24 -38.1%), 2 others.
  // Candidates less than one FWHM over the span from the sky rate are now set aside as static sources
  // (SearchResult::staticSources): seed 34's pair is one, so the bound 2 x Prob_false + 1 holds.
  // 2026-11-26 (H200 host, CPU, 199 s): the template's rim fixed (a ring of zeros around every star), a
  // saturated star's spikes subtracted instead of masked, moderate residual excess whitened instead of
  // masked: 20 of 20, 20 within one grid step, mean 1.021, 19 of 20 within 15% (seed 24 -17.5%, was -38%;
  // seed 28 +9.8%, was -23%; seed 21 +14.4%, was +18%), 1 other candidate (the edge one, SNR 7.12).
  // Then no mask at faint stars that single frames cannot see (a 5-pixel cross had been masked at each;
  // 2-core dev VM, 1543 s beside other builds): 20 of 20, 20 within one step, mean 1.025, 20 of 20 within 15%
  // (seed 24 -10.7%, seed 21 +14.5%), 1 other candidate (SNR 7.14).
  // Campaign ST_SEEDS=41-130 (H200 host's 16 cores, CPU, 2026-12-04 19:50 UTC, 40927ff: the PSF's catalogue,
  // isolated registration outliers kept linear): 90 of 90, 88 within one step, 90 within two, mean 1.005, 86
  // within 15%, 1 other candidate (seed 66's V = 23.1 partial-span star, 0.14 px/s off the sky rate), per-frame
  // registration on 0 seeds (seed 52 before: 1), sky rate within 0.0060 px/s (0.0121 before, seed 52).
  double sumPull2 = 0.0, maxPull = 0.0;
  for (double q : pulls) {
    sumPull2 += q * q;
    maxPull = std::max(maxPull, std::fabs(q));
  }
  const double rmsPull = pulls.empty() ? 0.0 : std::sqrt(sumPull2 / pulls.size());
  std::printf("segment positions: %d of %d segments, rms pull %.3f, largest |pull| %.2f (%zu pulls)\n",
              positions, segmentsCut, rmsPull, maxPull, pulls.size());
  for (int k = 0; k < 4; ++k)
    if (segCount[k] > 0)
      std::printf("segment %d of 4 (%d seeds): pull x mean %+.2f rms %.2f, y mean %+.2f rms %.2f\n", k + 1,
                  segCount[k], segSum[k][0] / segCount[k], std::sqrt(segSum2[k][0] / segCount[k]),
                  segSum[k][1] / segCount[k], std::sqrt(segSum2[k][1] / segCount[k]));
  // Each found asteroid a tracklet: nearly every segment gives a position; the errors honest to within the
  // spread an rms of ~150 unit normals has (~0.06) plus the fit's model error.
  EXPECT_GE(positions, 0.9 * segmentsCut);
  EXPECT_GE(segmentsCut, 2 * found);
  EXPECT_GT(rmsPull, 0.75);
  EXPECT_LT(rmsPull, 1.3);
  EXPECT_LT(maxPull, 5.0);
  EXPECT_EQ(found, seeds);
  EXPECT_EQ(oneStep, seeds);
  EXPECT_EQ(onVelocity, seeds);
  EXPECT_NEAR(mean, 1.0, 0.05);
  EXPECT_EQ(within15, seeds);
  EXPECT_LE(others, 2.0 * expectedFalse + 1.0);
  EXPECT_EQ(perFrame, 0);  // each one also failed above, with its seed
}

}  // namespace
}  // namespace st::pipeline

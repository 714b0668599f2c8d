// The tracklet of a fit (candidate::fitCandidate's segment positions, what a submission to the MPC gives per
// object): on the simulator's "small" preset (a CCD, stars drifting, one mover, a TAN WCS), each position
// at the mean time of its segment's frames (its MJD the cube's t_ref plus that offset), on the truth's track
// within its errors, and on the sky where the frames' WCS puts that pixel at that time (the stars having
// moved by the sky rate since the first frame, whose WCS it is), with errors of the plate scale times the
// pixel errors. The slow tests measure the errors' honesty over many movers (test_pipeline_seeds_slow.cpp,
// test_pipeline_real_injection_slow.cpp).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "st/candidate/candidate_fit.hpp"
#include "st/io/wcs.hpp"
#include "st/pipeline/preprocess.hpp"
#include "st/sim/simulator.hpp"
#include "st/vet/segments.hpp"

namespace st::candidate {
namespace {

TEST(Tracklet, SegmentsKeepEachNearTheDetectionThreshold) {
  EXPECT_EQ(trackletSegments(15.9), 4);  // the demo: 4 of SNR ~8
  EXPECT_EQ(trackletSegments(14.0), 4);
  EXPECT_EQ(trackletSegments(13.9), 3);
  EXPECT_EQ(trackletSegments(12.2), 3);
  EXPECT_EQ(trackletSegments(12.0), 2);
  EXPECT_EQ(trackletSegments(5.0), 2);  // fewer than two is no tracklet
  EXPECT_EQ(trackletSegments(300.0), 4);
  EXPECT_EQ(trackletSegments(std::numeric_limits<double>::quiet_NaN()), 2);
}

TEST(Tracklet, PositionsOfTheSmallPresetAtTheirOwnTimesOnTheTrackAndSky) {
  NullProgress p;
  CancelToken c;
  sim::SimResult sim = sim::simulate(sim::preset("small"), 7, p, c);
  const sim::Truth truth = sim.truth;
  ASSERT_FALSE(truth.objects.empty());
  const sim::TruthObject& o = truth.objects.front();
  pipeline::PreprocessParams params;
  params.masters = sim::exactMasters(sim);
  const pipeline::Prepared prep = pipeline::preprocess(std::move(sim.cube), params, p, c);
  ASSERT_TRUE(prep.frames.wcs);
  search::Candidate cell;
  cell.x = static_cast<int>(std::lround(o.xRefPx));
  cell.y = static_cast<int>(std::lround(o.yRefPx));
  cell.v = {o.vxPxPerS, o.vyPxPerS};
  const FitSummary fit = fitCandidate(prep, cell, c);
  ASSERT_TRUE(fit.converged()) << fit.message;
  ASSERT_TRUE(fit.segments);
  const SegmentSummary& seg = *fit.segments;
  const int k = trackletSegments(fit.snr);
  EXPECT_EQ(seg.positionSegments, k);
  ASSERT_GE(seg.positions.size(), 2u) << "fit SNR " << fit.snr;

  const std::vector<double> t = prep.frames.timeOffsetsS();
  const auto parts = vet::splitEqualTime(t, k);
  std::printf("fit SNR %.1f: %zu of %d segment positions\n", fit.snr, seg.positions.size(), k);
  int previous = 0;
  for (const SegmentPosition& q : seg.positions) {
    SCOPED_TRACE(q.segment);
    ASSERT_GT(q.segment, previous);  // in time order, each segment once
    ASSERT_LE(q.segment, k);
    previous = q.segment;
    double mean = 0.0;
    for (std::size_t n : parts[q.segment - 1])
      mean += t[n] / static_cast<double>(parts[q.segment - 1].size());
    EXPECT_NEAR(q.tOffsetS, mean, 1e-9);
    EXPECT_NEAR(q.mjdUtc, prep.frames.tRefMjd() + q.tOffsetS / 86400.0, 1e-10);
    // On the truth's track at its own time, within 5 of its errors.
    EXPECT_GT(q.sigmaXPx, 0.0);
    EXPECT_GT(q.sigmaYPx, 0.0);
    EXPECT_LT(std::abs(q.x - (o.xRefPx + o.vxPxPerS * q.tOffsetS)), 5.0 * q.sigmaXPx);
    EXPECT_LT(std::abs(q.y - (o.yRefPx + o.vyPxPerS * q.tOffsetS)), 5.0 * q.sigmaYPx);
    std::printf("segment %d at %+.2f s: (%.3f, %.3f) +- (%.3f, %.3f) px, truth (%.3f, %.3f), SNR %.1f\n",
                q.segment, q.tOffsetS, q.x, q.y, q.sigmaXPx, q.sigmaYPx, o.xRefPx + o.vxPxPerS * q.tOffsetS,
                o.yRefPx + o.vyPxPerS * q.tOffsetS, q.snr);
    // On the sky: the first frame's WCS at the pixel the stars then occupied.
    ASSERT_TRUE(q.raDeg && q.decDeg && q.sigmaRaArcsec && q.sigmaDecArcsec);
    const double dt = q.tOffsetS - t.front();
    const auto sky = prep.frames.wcs->pixelToSky(q.x - prep.skyRate.vx * dt, q.y - prep.skyRate.vy * dt);
    EXPECT_NEAR(*q.raDeg, sky.raDeg, 1e-9);
    EXPECT_NEAR(*q.decDeg, sky.decDeg, 1e-9);
    // The errors on the sky: the pixel errors through the plate scale (the WCS has square pixels).
    EXPECT_NEAR(*q.sigmaRaArcsec / (q.sigmaXPx * truth.plateScaleArcsecPerPx), 1.0, 0.1);
    EXPECT_NEAR(*q.sigmaDecArcsec / (q.sigmaYPx * truth.plateScaleArcsecPerPx), 1.0, 0.1);
  }
}

}  // namespace
}  // namespace st::candidate

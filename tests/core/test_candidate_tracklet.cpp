// The tracklet of a fit (candidate::fitCandidate's segment positions, what a submission to the MPC gives per
// object): on the simulator's "small" preset (a CCD, stars drifting, one mover, a TAN WCS), each position
// at the mean time of its segment's frames (its MJD the cube's t_ref plus that offset), on the truth's track
// within its errors, and on the sky where the frames' WCS puts that pixel at that time (the stars having
// moved by the sky rate since the first frame, whose WCS it is), with errors of the plate scale times the
// pixel errors. The slow tests measure the errors' honesty over many movers (test_pipeline_seeds_slow.cpp,
// test_pipeline_real_injection_slow.cpp).
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <iterator>
#include <limits>

#include "st/candidate/candidate_fit.hpp"
#include "st/io/fits_reader.hpp"
#include "st/io/wcs.hpp"
#include "st/pipeline/preprocess.hpp"
#include "st/report/regions.hpp"
#include "st/report/report_bundle.hpp"
#include "st/sim/simulator.hpp"
#include "st/vet/segments.hpp"
#include "test_support.hpp"

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

// Registered frames whose first frame sits at an offset from the linear sky-rate model (dithers, guiding
// drift: FrameInfo::offsetXPx/offsetYPx) fit in the registration's coordinates; the sky positions must map
// through the first frame's own pixels. The same frames with every frame's registration offset (3, -2) px and
// the candidate moved by (-3, +2) are the same observation: the same RA/Dec (before 2026-12-05 they were off
// by the first frame's offset, ~1 arcsec here).
TEST(Tracklet, SkyPositionsFollowTheFirstFramesRegistrationOffset) {
  NullProgress p;
  CancelToken c;
  sim::SimResult sim = sim::simulate(sim::preset("small"), 7, p, c);
  const sim::TruthObject o = sim.truth.objects.front();
  pipeline::PreprocessParams params;
  params.masters = sim::exactMasters(sim);
  const pipeline::Prepared prep = pipeline::preprocess(std::move(sim.cube), params, p, c);
  ASSERT_FALSE(prep.frames.hasFrameOffsets());
  search::Candidate cell;
  cell.x = static_cast<int>(std::lround(o.xRefPx));
  cell.y = static_cast<int>(std::lround(o.yRefPx));
  cell.v = {o.vxPxPerS, o.vyPxPerS};
  const FitSummary plain = fitCandidate(prep, cell, c);
  FrameCube shifted = prep.frames;
  for (auto& info : shifted.info()) {
    info.offsetXPx = 3.0;
    info.offsetYPx = -2.0;
  }
  search::Candidate moved = cell;
  moved.x -= 3;
  moved.y += 2;
  const FitSummary offset = fitCandidate(shifted, prep, moved, c);
  ASSERT_TRUE(plain.sky && offset.sky && plain.segments && offset.segments);
  EXPECT_NEAR(offset.x, plain.x - 3.0, 1e-3);
  const double cosDec = std::cos(plain.sky->decDeg * M_PI / 180.0);
  EXPECT_NEAR((offset.sky->raDeg - plain.sky->raDeg) * cosDec * 3600.0, 0.0, 1e-3);
  EXPECT_NEAR((offset.sky->decDeg - plain.sky->decDeg) * 3600.0, 0.0, 1e-3);
  ASSERT_EQ(offset.segments->positions.size(), plain.segments->positions.size());
  for (std::size_t k = 0; k < plain.segments->positions.size(); ++k) {
    const auto& a = plain.segments->positions[k];
    const auto& b = offset.segments->positions[k];
    EXPECT_NEAR((*b.raDeg - *a.raDeg) * cosDec * 3600.0, 0.0, 1e-3) << "segment " << a.segment;
    EXPECT_NEAR((*b.decDeg - *a.decDeg) * 3600.0, 0.0, 1e-3) << "segment " << a.segment;
  }
  // The DS9 regions' mapping of the report: the same point through either cube.
  const auto viaPlain = report::skyMappingAtTRef(prep.frames, prep.skyRate)(plain.x, plain.y);
  const auto viaOffset = report::skyMappingAtTRef(shifted, prep.skyRate)(offset.x, offset.y);
  EXPECT_NEAR((viaOffset.raDeg - viaPlain.raDeg) * cosDec * 3600.0, 0.0, 1e-3);
  EXPECT_NEAR((viaOffset.decDeg - viaPlain.decDeg) * 3600.0, 0.0, 1e-3);
  EXPECT_NEAR((viaPlain.raDeg - plain.sky->raDeg) * cosDec * 3600.0, 0.0, 1e-6);
}

// The GUI reports from the frames it loaded, which carry no registration, with the prepared frames'
// offsets beside them (ReportRequest::frameOffsets): its FITS stacks and DS9 regions must be those of frames
// that carry the offsets themselves (the CLI's prepared cube).
TEST(Tracklet, ReportWithFrameOffsetsGivenApartEqualsFramesCarryingThem) {
  NullProgress p;
  CancelToken c;
  const sim::SimResult sim = sim::simulate(sim::preset("small"), 7, p, c);
  ASSERT_TRUE(sim.cube.wcs);
  auto loaded = std::make_shared<const FrameCube>(sim.cube);
  auto carrying = std::make_shared<FrameCube>(sim.cube);
  std::vector<PixelOffset> offsets;
  for (std::size_t n = 0; n < carrying->frameCount(); ++n) {
    const PixelOffset o{2.0 + static_cast<double>(n % 3), -1.0 - static_cast<double>(n % 2)};  // a dither
    carrying->info()[n].offsetXPx = o.x;
    carrying->info()[n].offsetYPx = o.y;
    offsets.push_back(o);
  }
  nlohmann::json search{{"t_ref_mjd", sim.truth.tRefMjd}, {"psf_fwhm_px", 2.5}};
  search["sky_rate"] = {{"vx_px_s", sim.truth.skyVxPxPerS}, {"vy_px_s", sim.truth.skyVyPxPerS}};
  const sim::TruthObject& o = sim.truth.objects.front();
  search["candidates"] = {{{"x", static_cast<int>(o.xRefPx)},
                           {"y", static_cast<int>(o.yRefPx)},
                           {"vx_px_s", o.vxPxPerS},
                           {"vy_px_s", o.vyPxPerS},
                           {"snr", 12.0}}};
  const session::Session s = session::fromSearchJson(search);
  test::TempDir dir;
  const auto run = [&](std::shared_ptr<const FrameCube> raw, const std::vector<PixelOffset>& given,
                       const std::string& stem) {
    report::ReportRequest r;
    r.session = s;
    r.raw = std::move(raw);
    r.frameOffsets = given;
    r.regions = report::regionContext(r.raw.get(), r.session, r.frameOffsets);
    r.files[report::ReportFile::Ds9] = (dir / (stem + ".reg")).string();
    r.stacksStem = (dir / stem).string();
    r.stackChoice = report::StackChoice::All;
    (void)report::writeReports(r, p, c);
  };
  run(loaded, offsets, "given");
  run(carrying, {}, "carried");
  run(loaded, {}, "none");
  const auto text = [&](const std::string& name) {
    std::ifstream in(dir / name);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  EXPECT_EQ(text("given.reg"), text("carried.reg"));
  EXPECT_NE(text("none.reg"), text("carried.reg"));  // the offsets matter here
  io::LoadOptions lo;
  lo.startMjd = 60000.0;
  lo.frameRateHz = 1.0;
  for (const char* kind : {"_c001_object.fits", "_c001_sky.fits"}) {
    SCOPED_TRACE(kind);
    const FrameCube a = io::loadFrames({(dir / (std::string("given") + kind)).string()}, lo, p, c);
    const FrameCube b = io::loadFrames({(dir / (std::string("carried") + kind)).string()}, lo, p, c);
    ASSERT_EQ(a.pixels().size(), b.pixels().size());
    EXPECT_TRUE(std::equal(a.pixels().begin(), a.pixels().end(), b.pixels().begin()));
    ASSERT_TRUE(a.wcs && b.wcs);
    const auto sa = a.wcs->pixelToSky(40.0, 30.0), sb = b.wcs->pixelToSky(40.0, 30.0);
    EXPECT_EQ(sa.raDeg, sb.raDeg);
    EXPECT_EQ(sa.decDeg, sb.decDeg);
  }
}

}  // namespace
}  // namespace st::candidate

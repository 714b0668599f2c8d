// FITS stacks with a WCS moved to t_ref and provenance, read back through our reader; detections and DS9
// marks from a session's labels.
#include <gtest/gtest.h>

#include "st/common/error.hpp"
#include "st/io/fits_reader.hpp"
#include "st/io/wcs.hpp"
#include "st/report/fits_stack.hpp"
#include "st/report/report_bundle.hpp"
#include "st/report/session_report.hpp"
#include "test_support.hpp"

namespace st::report {
namespace {

std::shared_ptr<const Wcs> tanWcs() {
  FitsHeader h;
  h.setString("CTYPE1", "RA---TAN");
  h.setString("CTYPE2", "DEC--TAN");
  h.setNumber("CRVAL1", 150.0);
  h.setNumber("CRVAL2", 30.0);
  h.setNumber("CRPIX1", 33.0);
  h.setNumber("CRPIX2", 17.0);
  h.setNumber("CD1_1", -0.3 / 3600.0);
  h.setNumber("CD1_2", 0.01 / 3600.0);
  h.setNumber("CD2_1", 0.02 / 3600.0);
  h.setNumber("CD2_2", 0.3 / 3600.0);
  std::vector<std::string> warnings;
  return Wcs::fromHeader(h, &warnings);
}

TEST(FitsStack, WcsMovedToTRefAndProvenanceReadBack) {
  test::TempDir dir;
  const auto wcs = tanWcs();
  ASSERT_NE(wcs, nullptr);
  Image img(64, 40);
  for (std::size_t i = 0; i < img.size(); ++i)
    img.pixels[i] = static_cast<float>(i % 97) - 3.5f;
  StackProvenance p;
  p.what = "candidate 2, IPSA";
  p.velocity = {1.25, -0.5};
  p.skyRate = {2.0, 0.5};
  p.tRefMjd = 60000.25;
  p.frames = 500;
  p.inputs = {"/data/a.fits", "/data/b.fits"};
  const double firstOffsetS = -15.0;  // the WCS is the first frame's, 15 s before t_ref
  const std::string path = (dir / "stack.fits").string();
  writeStackFits(path, img, p, wcs.get(), firstOffsetS);

  NullProgress progress;
  CancelToken cancel;
  io::LoadOptions options;
  options.startMjd = 60000.0;
  options.frameRateHz = 1.0;
  const FrameCube back = io::loadFrames({path}, options, progress, cancel);
  ASSERT_EQ(back.frameCount(), 1u);
  ASSERT_EQ(back.width(), 64);
  for (std::size_t i = 0; i < img.size(); ++i)
    ASSERT_EQ(back.frame(0)[i], img.pixels[i]) << i;
  const FitsHeader& h = back.header;
  EXPECT_DOUBLE_EQ(*h.getDouble("STVX"), 1.25);
  EXPECT_DOUBLE_EQ(*h.getDouble("SKYVY"), 0.5);
  EXPECT_DOUBLE_EQ(*h.getDouble("TREFMJD"), 60000.25);
  EXPECT_DOUBLE_EQ(*h.getDouble("WCSEPOCH"), 60000.25);
  EXPECT_DOUBLE_EQ(*h.getDouble("NFRAMES"), 500.0);
  EXPECT_EQ(*h.getString("STMODE"), "IPSA");
  EXPECT_NE(h.getString("SOFTWARE")->find("synthtrack"), std::string::npos);
  int history = 0;
  for (const auto& c : h.cards)
    history += c.key == "HISTORY" && (c.comment + c.value).find("/data/") != std::string::npos;
  EXPECT_EQ(history, 2);
  // A star at stack pixel (x, y) (its t_ref position) was at (x, y) + skyRate * (-15 s) in the first frame.
  ASSERT_NE(back.wcs, nullptr);
  for (const auto& [x, y] : {std::pair{0.0, 0.0}, {40.0, 12.5}, {63.0, 39.0}}) {
    const auto a = back.wcs->pixelToSky(x, y);
    const auto b = wcs->pixelToSky(x + p.skyRate.vx * firstOffsetS, y + p.skyRate.vy * firstOffsetS);
    EXPECT_NEAR(a.raDeg, b.raDeg, 1e-10);
    EXPECT_NEAR(a.decDeg, b.decDeg, 1e-10);
  }
  // Registered frames whose first frame sits at an offset (a dither): the stack's pixel is a registered
  // position, which lies at that offset in the first frame's own pixels.
  const std::string dithered = (dir / "dithered.fits").string();
  writeStackFits(dithered, img, p, wcs.get(), firstOffsetS, nullptr, {2.5, -1.0});
  const FrameCube backDithered = io::loadFrames({dithered}, options, progress, cancel);
  ASSERT_NE(backDithered.wcs, nullptr);
  for (const auto& [x, y] : {std::pair{0.0, 0.0}, {40.0, 12.5}}) {
    const auto a = backDithered.wcs->pixelToSky(x, y);
    const auto b =
        wcs->pixelToSky(x + p.skyRate.vx * firstOffsetS + 2.5, y + p.skyRate.vy * firstOffsetS - 1.0);
    EXPECT_NEAR(a.raDeg, b.raDeg, 1e-10);
    EXPECT_NEAR(a.decDeg, b.decDeg, 1e-10);
  }
}

session::Session labelled() {
  nlohmann::json j;
  j["t_ref_mjd"] = 60000.5;
  j["plate_scale_arcsec_px"] = 0.3;
  j["psf_fwhm_px"] = 3.0;
  j["candidates"] = nlohmann::json::array();
  for (int i = 0; i < 4; ++i)
    j["candidates"].push_back(
        {{"x", 10 * i}, {"y", 5}, {"vx_px_s", 1.0}, {"vy_px_s", 0.0}, {"snr", 8.0 + i}});
  j["candidates"][0]["fit"] = {{"status", "converged"}, {"x", 0.25},      {"y", 5.5},
                               {"vx_px_s", 1.1},        {"vy_px_s", 0.1}, {"ra_deg", 150.1},
                               {"dec_deg", -20.2},      {"snr", 9.5},     {"sigma_x_px", 0.1},
                               {"sigma_y_px", 0.2},     {"mag", 22.95}};
  j["candidates"][2]["fit"] = {{"status", "converged"}, {"x", 20.0}, {"y", 5.0}};
  session::Session s = session::fromSearchJson(j);
  s.candidates[0].label = session::Label::Real;
  s.candidates[1].label = session::Label::Artifact;
  s.candidates[1].reason = session::ArtifactReason::CosmicRay;
  s.candidates[2].label = session::Label::Real;  // no sky position
  return s;
}

TEST(SessionReport, OnlyRealCandidatesWithASkyPositionAreReported) {
  std::vector<std::string> warnings;
  const auto d = realDetections(labelled(), TrackletPositions::Fit, warnings);
  ASSERT_EQ(d.size(), 1u);
  EXPECT_EQ(d[0].trkSub, "st00001");
  EXPECT_DOUBLE_EQ(d[0].raDeg, 150.1);
  EXPECT_DOUBLE_EQ(d[0].decDeg, -20.2);
  EXPECT_DOUBLE_EQ(d[0].mjdUtc, 60000.5);
  EXPECT_DOUBLE_EQ(d[0].snr, 9.5);
  EXPECT_NEAR(*d[0].sigmaRaArcsec, 0.03, 1e-15);
  EXPECT_NEAR(*d[0].sigmaDecArcsec, 0.06, 1e-15);
  EXPECT_DOUBLE_EQ(*d[0].mag, 22.95);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("candidate 3"), std::string::npos) << warnings[0];
}

// Segment positions of the candidate of labelled(): n segments, the first `withSky` with a sky position.
void addSegmentPositions(session::Session& s, int n, int withSky) {
  candidate::SegmentSummary seg;
  for (int k = 0; k < n; ++k) {
    candidate::SegmentPosition p;
    p.segment = k + 1;
    p.tOffsetS = -11.25 + 7.5 * k;
    p.mjdUtc = 60000.5 + p.tOffsetS / 86400.0;
    p.x = 0.25 + 1.1 * p.tOffsetS;
    p.y = 5.5 + 0.1 * p.tOffsetS;
    p.sigmaXPx = 0.2 + 0.01 * k;
    p.sigmaYPx = 0.4;
    p.snr = 4.5 + k;
    if (k < withSky) {
      p.raDeg = 150.1 + 1e-4 * k;
      p.decDeg = -20.2 - 1e-5 * k;
    }
    if (k == 0) p.sigmaRaArcsec = 0.07;  // the others from the pixel errors and the plate scale
    if (k == 0) p.sigmaDecArcsec = 0.09;
    seg.positions.push_back(p);
  }
  s.candidates[0].fit->segments = seg;
}

// With segment positions (the default), an object labelled real is a tracklet: one detection per segment
// position on the sky, each at its own time with its own SNR and errors, all under one trkSub.
TEST(SessionReport, ARealObjectIsATrackletOfItsSegmentPositions) {
  session::Session s = labelled();
  addSegmentPositions(s, 4, 4);
  std::vector<std::string> warnings;
  const auto d = realDetections(s, SubmissionSettings{}.positions, warnings);
  ASSERT_EQ(d.size(), 4u);
  for (int k = 0; k < 4; ++k) {
    SCOPED_TRACE(k);
    EXPECT_EQ(d[k].trkSub, "st00001");
    EXPECT_DOUBLE_EQ(d[k].mjdUtc, 60000.5 + (-11.25 + 7.5 * k) / 86400.0);
    EXPECT_DOUBLE_EQ(d[k].raDeg, 150.1 + 1e-4 * k);
    EXPECT_DOUBLE_EQ(d[k].decDeg, -20.2 - 1e-5 * k);
    EXPECT_DOUBLE_EQ(d[k].snr, 4.5 + k);
    EXPECT_DOUBLE_EQ(*d[k].mag, 22.95);
    EXPECT_NEAR(*d[k].sigmaRaArcsec, k == 0 ? 0.07 : (0.2 + 0.01 * k) * 0.3, 1e-15);
    EXPECT_NEAR(*d[k].sigmaDecArcsec, k == 0 ? 0.09 : 0.12, 1e-15);
  }
  // The files count the positions and the objects apart.
  {
    test::TempDir dir;
    ReportRequest r;
    r.session = s;
    r.submission.stationCode = "291";
    r.submission.observers = "A. Observer";
    r.submission.apertureM = 0.5;
    r.submission.astCat = "Gaia3";
    r.files[ReportFile::AdesPsv] = (dir / "out.psv").string();
    NullProgress progress;
    CancelToken cancel;
    const ReportOutcome out = writeReports(r, progress, cancel);
    EXPECT_EQ(out.detections, 4u);
    EXPECT_EQ(out.objects, 1u);
  }
  // Each low-SNR position is named with its segment.
  const auto low = lowSnrWarnings(d, 7.0);
  ASSERT_EQ(low.size(), 3u);
  EXPECT_EQ(low[0].rfind("st00001 segment 1: SNR 4.50 is below the safe 7.0", 0), 0u) << low[0];
  // Segment positions without a sky position are left out; with two or more on the sky it is still a
  // tracklet.
  addSegmentPositions(s, 4, 2);
  warnings.clear();
  EXPECT_EQ(realDetections(s, TrackletPositions::Segments, warnings).size(), 2u);
  ASSERT_EQ(warnings.size(), 1u);  // candidate 3's missing sky position only
  EXPECT_EQ(warnings[0].find("candidate 1"), std::string::npos) << warnings[0];
}

// The candidates file (flat keys, what `report` reads back) keeps the segment positions exactly.
TEST(SessionReport, SegmentPositionsSurviveTheCandidatesFile) {
  session::Session s = labelled();
  addSegmentPositions(s, 4, 3);
  const session::Session back = session::fromSearchJson(candidatesJson(s));
  ASSERT_TRUE(back.candidates[0].fit && back.candidates[0].fit->segments);
  EXPECT_EQ(back.candidates[0].fit->segments->positions, s.candidates[0].fit->segments->positions);
  EXPECT_FALSE(back.candidates[0].fit->segments->positions[3].raDeg);
  nlohmann::json broken = candidatesJson(s);
  broken["candidates"][0]["fit"]["segment_positions"][1].erase("mjd_utc");
  try {
    (void)session::fromSearchJson(broken);
    ADD_FAILURE() << "a segment position without its epoch was read";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("segment_positions[1]: missing key 'mjd_utc'"), std::string::npos)
        << e.what();
  }
}

// Fewer than two segment positions on the sky (a session written before they were kept, or failed segment
// fits): the whole fit's one position, with a warning that says the MPC needs two or more.
TEST(SessionReport, OneSegmentPositionFallsBackToTheWholeFitWithAWarning) {
  session::Session s = labelled();
  addSegmentPositions(s, 4, 1);
  std::vector<std::string> warnings;
  const auto d = realDetections(s, TrackletPositions::Segments, warnings);
  ASSERT_EQ(d.size(), 1u);
  EXPECT_DOUBLE_EQ(d[0].raDeg, 150.1);
  EXPECT_DOUBLE_EQ(d[0].mjdUtc, 60000.5);
  EXPECT_DOUBLE_EQ(d[0].snr, 9.5);
  ASSERT_EQ(warnings.size(), 2u);
  EXPECT_NE(warnings[0].find("candidate 1 has 1 segment position(s) on the sky"), std::string::npos)
      << warnings[0];
  EXPECT_NE(warnings[0].find("two or more"), std::string::npos) << warnings[0];
  // Asked for the whole fit's position, there is nothing to warn about.
  warnings.clear();
  EXPECT_EQ(realDetections(s, TrackletPositions::Fit, warnings).size(), 1u);
  EXPECT_EQ(warnings.size(), 1u);
}

// A real candidate is an observation only with a converged fit that has a sky position; the warning says
// which piece is missing (it blamed the WCS for a fit that had diverged).
TEST(SessionReport, EachMissingPieceOfARealCandidateIsNamed) {
  session::Session s = labelled();
  s.candidates[3].label = session::Label::Real;  // no fit at all
  s.candidates[1].label = session::Label::Real;
  s.candidates[1].fit = s.candidates[0].fit;  // with a sky position, but diverged
  s.candidates[1].fit->status = fit::FitStatus::Diverged;
  std::vector<std::string> warnings;
  const auto d = realDetections(s, TrackletPositions::Fit, warnings);
  ASSERT_EQ(d.size(), 1u);
  EXPECT_EQ(d[0].trkSub, "st00001");
  ASSERT_EQ(warnings.size(), 3u);
  EXPECT_NE(warnings[0].find("candidate 2 is labelled real but its fit did not converge"), std::string::npos)
      << warnings[0];
  EXPECT_NE(warnings[1].find("candidate 3 is labelled real but its fit has no sky position"), std::string::npos)
      << warnings[1];
  EXPECT_NE(warnings[2].find("candidate 4 is labelled real but has no accepted co-moving fit"), std::string::npos)
      << warnings[2];
}

// With no detection to submit, no ADES or 80-column file is written (an ADES file without an observation
// fails submit.xsd: obsData needs one), the files asked for are named as not written, and the rest is
// written.
TEST(SessionReport, AnEmptySubmissionIsNotWritten) {
  test::TempDir dir;
  ReportRequest r;
  r.session = labelled();
  r.session.candidates[0].label = session::Label::Unsure;  // the only real one with a sky position
  r.submission.stationCode = "291";
  r.submission.observers = "A. Observer";
  r.submission.apertureM = 0.5;
  r.submission.astCat = "Gaia3";
  const std::string psv = (dir / "out.psv").string(), xml = (dir / "out.xml").string(),
                    mpc = (dir / "out_mpc.txt").string(), csv = (dir / "out.csv").string();
  r.files[ReportFile::AdesPsv] = psv;
  r.files[ReportFile::AdesXml] = xml;
  r.files[ReportFile::Mpc80] = mpc;
  r.files[ReportFile::CandidatesCsv] = csv;
  NullProgress progress;
  CancelToken cancel;
  const ReportOutcome out = writeReports(r, progress, cancel);
  EXPECT_EQ(out.detections, 0u);
  EXPECT_EQ(out.notWritten, (std::vector<std::string>{psv, xml, mpc}));
  EXPECT_EQ(out.written, std::vector<std::string>{csv});
  for (const auto& path : {psv, xml, mpc})
    EXPECT_FALSE(std::filesystem::exists(path)) << path;
  EXPECT_TRUE(std::filesystem::exists(csv));
  ASSERT_FALSE(out.warnings.empty());
  EXPECT_NE(out.warnings.back().find("no ADES or MPC file written"), std::string::npos)
      << out.warnings.back();
  // With the candidate real again, all three are written.
  r.session.candidates[0].label = session::Label::Real;
  const ReportOutcome again = writeReports(r, progress, cancel);
  EXPECT_EQ(again.detections, 1u);
  EXPECT_TRUE(again.notWritten.empty());
  for (const auto& path : {psv, xml, mpc})
    EXPECT_TRUE(std::filesystem::exists(path)) << path;
  // Nothing to submit again: the earlier files stay, and each is said not to be this run's.
  r.session.candidates[0].label = session::Label::Unsure;
  const ReportOutcome stale = writeReports(r, progress, cancel);
  EXPECT_EQ(stale.notWritten.size(), 3u);
  int said = 0;
  for (const auto& w : stale.warnings)
    said += w.find("an earlier file, left as it was") != std::string::npos;
  EXPECT_EQ(said, 3);
}

TEST(SessionReport, RegionMarksUseFitsAndLabelColours) {
  const auto marks = regionMarks(labelled(), -5.0, 5.0);
  ASSERT_EQ(marks.size(), 4u);
  EXPECT_DOUBLE_EQ(marks[0].x, 0.25);  // the converged fit's position, not the search cell
  EXPECT_DOUBLE_EQ(marks[0].velocity->vx, 1.1);
  EXPECT_EQ(marks[0].color, "green");
  EXPECT_EQ(marks[1].color, "red");
  EXPECT_NE(marks[1].text.find("cosmic_ray"), std::string::npos);
  EXPECT_EQ(marks[3].color, "cyan");
  EXPECT_DOUBLE_EQ(marks[3].x, 30.0);
  EXPECT_DOUBLE_EQ(marks[3].radiusPx, 6.0);
}

}  // namespace
}  // namespace st::report

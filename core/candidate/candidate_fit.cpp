#include "st/candidate/candidate_fit.hpp"

#include <algorithm>
#include <cmath>

#include "st/astro/astrometry.hpp"
#include "st/astro/photometry.hpp"
#include "st/io/wcs.hpp"
#include "st/vet/segments.hpp"

namespace st::candidate {

FitSummary fitCandidate(const pipeline::Prepared& prepared, const search::Candidate& c, CancelToken& cancel) {
  return fitCandidate(prepared.frames, prepared, c, cancel);
}

int trackletSegments(double snr) noexcept {
  if (!(snr > 0.0) || !std::isfinite(snr)) return 2;
  const double k = std::floor((snr / kTrackletSnr) * (snr / kTrackletSnr));
  return static_cast<int>(std::clamp(k, 2.0, 4.0));
}

namespace {

// The segment positions of `seg` worth submitting: the segment's fit converged with errors, its signal is
// not missing (vet::SegmentMeasurement::missing), and it lies within kMaxPull of the whole fit's track on
// each axis (a segment fit that wandered off onto noise or a neighbour is not the object).
std::vector<SegmentPosition> positionsOf(const vet::SegmentReport& seg, const FrameCube& frames,
                                         Velocity skyRate) {
  constexpr double kMaxPull = 5.0;
  std::vector<SegmentPosition> out;
  for (const auto& m : seg.segments) {
    if (m.frames.empty() || m.missing || !m.fit.ok() || !(m.sigmaX > 0.0) || !(m.sigmaY > 0.0)) continue;
    if (std::abs(m.x - m.predictedX) > kMaxPull * m.sigmaX ||
        std::abs(m.y - m.predictedY) > kMaxPull * m.sigmaY)
      continue;
    SegmentPosition p{
        m.index + 1, m.fit.tRefMjd, m.tMidOffsetS, m.x, m.y, m.sigmaX, m.sigmaY, m.snr, {}, {}, {}, {}};
    if (frames.wcs) {
      const astro::SkyMeasurement sky = astro::skyMeasurement(frames, m.fit, skyRate);
      p.raDeg = sky.raDeg;
      p.decDeg = sky.decDeg;
      p.sigmaRaArcsec = sky.sigmaRaArcsec;
      p.sigmaDecArcsec = sky.sigmaDecArcsec;
    }
    out.push_back(p);
  }
  return out;
}

}  // namespace

bool amongLeftOutMovers(const std::vector<detect::MovingSource>& movers, double psfFwhmPx, double x,
                        double y) {
  const double radius = 2.0 * psfFwhmPx + 2.0;
  return std::any_of(movers.begin(), movers.end(), [&](const detect::MovingSource& m) {
    return m.moving && std::hypot(m.x - x, m.y - y) <= radius;
  });
}

fit::FitOptions fitOptions(const FrameCube& frames, const pipeline::Prepared& prepared,
                           const search::Candidate& c) {
  fit::FitOptions opt;
  opt.psf = prepared.psf;
  opt.sigmaN = prepared.sigmaN;
  opt.gain = astro::photoelectronsPerCount(frames.header);
  opt.excessNoise = astro::excessNoiseFactor(frames.header);
  opt.selfSubtraction = prepared.backgroundWindows;
  opt.sourceInBackground = !amongLeftOutMovers(prepared.movers, prepared.psf.fwhm(), c.x, c.y);
  return opt;
}

FitSummary fitCandidate(const FrameCube& frames, const pipeline::Prepared& prepared,
                        const search::Candidate& c, CancelToken& cancel,
                        const fit::IterationCallback& onIteration, fit::FitResult* result) {
  const fit::FitOptions opt = fitOptions(frames, prepared, c);
  const fit::FitResult f = fit::fitComoving(frames, fit::startFromCandidate(c), opt, onIteration, cancel);
  FitSummary s = summarize(f);
  if (f.sigmaN > 0.0) {
    const vet::SegmentOptions check;  // K = 4, the paper's
    const vet::SegmentReport seg = vet::checkSegments(frames, f, opt, check, cancel);
    SegmentSummary summary{seg.flagged(), seg.reasons, {}, {}};
    for (const auto& m : seg.segments)
      summary.snr.push_back(m.forcedSnr);
    if (f.ok()) {
      // The tracklet: the check's own segments when their number suits the fit's SNR, else segments of
      // their own (never more than the frames).
      vet::SegmentOptions tracklet = check;
      tracklet.segments = std::min(trackletSegments(f.snr), static_cast<int>(frames.frameCount()));
      summary.positionSegments = tracklet.segments;
      summary.positions =
          tracklet.segments == check.segments
              ? positionsOf(seg, frames, prepared.skyRate)
              : positionsOf(vet::checkSegments(frames, f, opt, tracklet, cancel), frames, prepared.skyRate);
    }
    s.segments = std::move(summary);
  }
  if (f.ok() && frames.wcs) {
    // The first frame's WCS: the stars have moved by the sky rate since then (and sit at its offset).
    const astro::SkyMeasurement sky = astro::skyMeasurement(frames, f, prepared.skyRate);
    s.sky = SkyPosition{sky.raDeg, sky.decDeg, sky.rateDegPerDay, sky.rateArcsecPerMin, sky.positionAngleDeg};
  }
  if (result != nullptr) *result = f;
  return s;
}

}  // namespace st::candidate

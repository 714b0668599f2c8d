#include "st/candidate/candidate_fit.hpp"

#include "st/astro/astrometry.hpp"
#include "st/astro/photometry.hpp"
#include "st/io/wcs.hpp"
#include "st/vet/segments.hpp"

namespace st::candidate {

FitSummary fitCandidate(const pipeline::Prepared& prepared, const search::Candidate& c, CancelToken& cancel) {
  return fitCandidate(prepared.frames, prepared, c, cancel);
}

FitSummary fitCandidate(const FrameCube& frames, const pipeline::Prepared& prepared,
                        const search::Candidate& c, CancelToken& cancel,
                        const fit::IterationCallback& onIteration, fit::FitResult* result) {
  fit::FitOptions opt;
  opt.psf = prepared.psf;
  opt.sigmaN = prepared.sigmaN;
  opt.gain = astro::photoelectronsPerCount(frames.header);
  opt.excessNoise = astro::excessNoiseFactor(frames.header);
  const fit::FitResult f = fit::fitComoving(frames, fit::startFromCandidate(c), opt, onIteration, cancel);
  FitSummary s = summarize(f);
  // A FITS WCS belongs to the first frame; the stars have moved by the sky rate since then.
  const double firstOffset = frames.timeOffsetsS().front();
  if (f.sigmaN > 0.0) {
    const vet::SegmentReport seg = vet::checkSegments(frames, f, opt, vet::SegmentOptions{}, cancel);
    SegmentSummary summary{seg.flagged(), seg.reasons, {}, {}};
    for (const auto& m : seg.segments) {
      summary.snr.push_back(m.forcedSnr);
      if (!f.ok() || !m.fit.ok() || !(m.sigmaX > 0.0) || !(m.sigmaY > 0.0)) continue;
      SegmentPosition p{
          m.index + 1, m.fit.tRefMjd, m.tMidOffsetS, m.x, m.y, m.sigmaX, m.sigmaY, m.snr, {}, {}, {}, {}};
      if (frames.wcs) {
        const astro::SkyMeasurement sky =
            astro::skyMeasurement(*frames.wcs, m.fit, prepared.skyRate, firstOffset);
        p.raDeg = sky.raDeg;
        p.decDeg = sky.decDeg;
        p.sigmaRaArcsec = sky.sigmaRaArcsec;
        p.sigmaDecArcsec = sky.sigmaDecArcsec;
      }
      summary.positions.push_back(p);
    }
    s.segments = std::move(summary);
  }
  if (f.ok() && frames.wcs) {
    const astro::SkyMeasurement sky = astro::skyMeasurement(*frames.wcs, f, prepared.skyRate, firstOffset);
    s.sky = SkyPosition{sky.raDeg, sky.decDeg, sky.rateDegPerDay, sky.rateArcsecPerMin, sky.positionAngleDeg};
  }
  if (result != nullptr) *result = f;
  return s;
}

}  // namespace st::candidate

#include "candidate_fit.hpp"

#include "st/astro/astrometry.hpp"
#include "st/fit/comoving_fit.hpp"
#include "st/io/wcs.hpp"
#include "st/vet/segments.hpp"

namespace st::app {

nlohmann::json fitCandidateJson(const pipeline::Prepared& prepared, const search::Candidate& c, double gain,
                                CancelToken& cancel) {
  return fitCandidateJson(prepared.frames, prepared, c, gain, cancel);
}

nlohmann::json fitCandidateJson(const FrameCube& frames, const pipeline::Prepared& prepared,
                                const search::Candidate& c, double gain, CancelToken& cancel,
                                const fit::IterationCallback& onIteration, fit::FitResult* result) {
  fit::FitOptions opt;
  opt.psf = prepared.psf;
  opt.sigmaN = prepared.sigmaN;
  opt.gain = gain;
  const fit::FitResult f = fit::fitComoving(frames, fit::startFromCandidate(c), opt, onIteration, cancel);
  nlohmann::json j{{"status", fit::toString(f.status)},
                   {"message", f.message},
                   {"iterations", f.iterations},
                   {"x", f.params.xc},
                   {"y", f.params.yc},
                   {"vx_px_s", f.params.v.vx},
                   {"vy_px_s", f.params.v.vy},
                   {"sigma_x_px", f.sigmaNoiseModel[fit::kXc]},
                   {"sigma_y_px", f.sigmaNoiseModel[fit::kYc]},
                   {"sigma_vx_px_s", f.sigmaNoiseModel[fit::kVx]},
                   {"sigma_vy_px_s", f.sigmaNoiseModel[fit::kVy]},
                   {"sigma_pos_paper_px", f.sigmaPosPaper},
                   {"sigma_vel_paper_px_s", f.sigmaVelPaper},
                   {"photons_per_frame", f.photonsPerFrame},
                   {"snr", f.snr}};
  if (f.sigmaN > 0.0) {
    const vet::SegmentReport seg = vet::checkSegments(frames, f, opt, vet::SegmentOptions{}, cancel);
    j["segments_flagged"] = seg.flagged();
    j["segment_reasons"] = seg.reasons;
    nlohmann::json snrs = nlohmann::json::array();
    for (const auto& s : seg.segments)
      snrs.push_back(s.forcedSnr);
    j["segment_snr"] = snrs;
  }
  if (f.ok() && frames.wcs) {
    // A FITS WCS belongs to the first frame; the stars have moved by the sky rate since then.
    const double firstOffset = frames.timeOffsetsS().front();
    const astro::SkyMeasurement sky = astro::skyMeasurement(*frames.wcs, f, prepared.skyRate, firstOffset);
    j["ra_deg"] = sky.raDeg;
    j["dec_deg"] = sky.decDeg;
    j["rate_deg_day"] = sky.rateDegPerDay;
    j["rate_arcsec_min"] = sky.rateArcsecPerMin;
    j["pa_deg"] = sky.positionAngleDeg;
  }
  if (result != nullptr) *result = f;
  return j;
}

}  // namespace st::app

#include "st/report/session_report.hpp"

#include <cstdio>

#include "st/fit/comoving_fit.hpp"

namespace st::report {
namespace {

std::optional<double> number(const nlohmann::json& j, const char* key) {
  if (j.is_object() && j.contains(key) && j[key].is_number()) return j[key].get<double>();
  return std::nullopt;
}

}  // namespace

std::vector<AstrometricDetection> realDetections(const session::Session& s, TrackletPositions positions,
                                                 std::vector<std::string>& warnings,
                                                 const std::string& prefix) {
  std::vector<AstrometricDetection> out;
  const auto scale = number(s.search, "plate_scale_arcsec_px");
  // Pixel errors -> arcsec through the mean scale (the axes' orientation is not in the fit record).
  const auto arcsec = [&](double px) {
    return scale && px > 0.0 ? std::optional(px * *scale) : std::nullopt;
  };
  for (std::size_t i = 0; i < s.candidates.size(); ++i) {
    const auto& c = s.candidates[i];
    if (c.label != session::Label::Real) continue;
    // Only a converged co-moving fit with a sky position is an observation; each missing piece is named.
    const std::string which = "candidate " + std::to_string(i + 1) + " is labelled real but ";
    if (!c.fit) {
      warnings.push_back(which + "has no accepted co-moving fit (fit it and accept the fit): not reported");
      continue;
    }
    if (!c.fit->converged()) {
      warnings.push_back(which + "its fit did not converge (" + fit::toString(c.fit->status) +
                         "): not reported; fit it again");
      continue;
    }
    if (!c.fit->sky) {
      warnings.push_back(which +
                         "its fit has no sky position (the frames have no WCS: plate-solve them, or give the "
                         "report a WCS file): not reported");
      continue;
    }
    const candidate::FitSummary& f = *c.fit;
    AstrometricDetection d;
    std::string number1 = std::to_string(i + 1);
    const std::size_t width = prefix.size() < 7 ? 7 - prefix.size() : 0;
    if (number1.size() < width) number1.insert(0, width - number1.size(), '0');
    d.trkSub = prefix + number1;
    d.mag = f.mag;
    if (f.band) d.band = *f.band;
    if (positions == TrackletPositions::Segments) {
      std::vector<AstrometricDetection> tracklet;
      if (f.segments)
        for (const auto& p : f.segments->positions) {
          if (!p.raDeg || !p.decDeg || !(p.mjdUtc > 0.0)) continue;
          AstrometricDetection e = d;
          e.raDeg = *p.raDeg;
          e.decDeg = *p.decDeg;
          e.mjdUtc = p.mjdUtc;
          e.snr = p.snr;
          e.segment = p.segment;
          e.sigmaRaArcsec = p.sigmaRaArcsec ? p.sigmaRaArcsec : arcsec(p.sigmaXPx);
          e.sigmaDecArcsec = p.sigmaDecArcsec ? p.sigmaDecArcsec : arcsec(p.sigmaYPx);
          tracklet.push_back(e);
        }
      if (tracklet.size() >= 2) {
        out.insert(out.end(), tracklet.begin(), tracklet.end());
        continue;
      }
      const std::string why =
          !f.segments ? "its fit has no segment check (the noise level was unknown)"
          : f.segments->positionSegments == 0
              ? "its fit was accepted before segment positions were kept: fit it again"
          : f.segments->positions.size() > tracklet.size()
              ? "its segment positions have no RA/Dec: give the report the frames' WCS"
              : "of its " + std::to_string(f.segments->positionSegments) +
                    " segments the others' fits failed, missed the signal or left the track";
      warnings.push_back(
          "candidate " + std::to_string(i + 1) + " has " + std::to_string(tracklet.size()) +
          " segment position(s) on the sky (" + why +
          "): its one whole-fit position is reported, and the MPC links a new object only from "
          "two or more");
    }
    d.raDeg = f.sky->raDeg;
    d.decDeg = f.sky->decDeg;
    d.mjdUtc = f.tRefMjd.value_or(number(s.search, "t_ref_mjd").value_or(0.0));
    d.snr = f.snr;
    d.sigmaRaArcsec = f.sigmaRaArcsec ? f.sigmaRaArcsec : arcsec(f.sigma.xPx);
    d.sigmaDecArcsec = f.sigmaDecArcsec ? f.sigmaDecArcsec : arcsec(f.sigma.yPx);
    if (d.mjdUtc <= 0.0) {
      warnings.push_back("candidate " + std::to_string(i + 1) + " has no epoch (t_ref_mjd): not reported");
      continue;
    }
    out.push_back(d);
  }
  return out;
}

Velocity sessionSkyRate(const session::Session& s) {
  if (!s.search.contains("sky_rate")) return {};
  return {s.search["sky_rate"].value("vx_px_s", 0.0), s.search["sky_rate"].value("vy_px_s", 0.0)};
}

std::vector<RegionMark> regionMarks(const session::Session& s, double trackStartS, double trackEndS) {
  std::vector<RegionMark> out;
  const Velocity sky = sessionSkyRate(s);
  const double fwhm = number(s.search, "psf_fwhm_px").value_or(2.5);
  for (std::size_t i = 0; i < s.candidates.size(); ++i) {
    const auto& c = s.candidates[i];
    RegionMark m;
    const vet::Track track = c.track();
    m.x = track.x;
    m.y = track.y;
    m.radiusPx = 2.0 * fwhm;
    if (trackEndS > trackStartS) {
      m.velocity = track.v;
      m.skyRate = sky;
      m.trackStartS = trackStartS;
      m.trackEndS = trackEndS;
    }
    m.color = candidate::labelColour(c.label);
    char buf[128];
    std::snprintf(buf, sizeof buf, "#%zu SNR %.1f %s", i + 1, c.snr(), session::toString(c.label));
    m.text = buf;
    if (c.label == session::Label::Artifact) m.text += std::string(" (") + session::toString(c.reason) + ")";
    out.push_back(m);
  }
  return out;
}

}  // namespace st::report

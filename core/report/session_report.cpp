#include "st/report/session_report.hpp"

#include <cstdio>

namespace st::report {
namespace {

std::optional<double> number(const nlohmann::json& j, const char* key) {
  if (j.is_object() && j.contains(key) && j[key].is_number()) return j[key].get<double>();
  return std::nullopt;
}

}  // namespace

std::vector<AstrometricDetection> realDetections(const session::Session& s,
                                                 std::vector<std::string>& warnings,
                                                 const std::string& prefix) {
  std::vector<AstrometricDetection> out;
  const auto scale = number(s.search, "plate_scale_arcsec_px");
  for (std::size_t i = 0; i < s.candidates.size(); ++i) {
    const auto& c = s.candidates[i];
    if (c.label != session::Label::Real) continue;
    const auto ra = number(c.fit, "ra_deg"), dec = number(c.fit, "dec_deg");
    if (!ra || !dec) {
      warnings.push_back(
          "candidate " + std::to_string(i + 1) +
          " is labelled real but has no fitted sky position (fit with a WCS first): not reported");
      continue;
    }
    AstrometricDetection d;
    std::string number1 = std::to_string(i + 1);
    const std::size_t width = prefix.size() < 7 ? 7 - prefix.size() : 0;
    if (number1.size() < width) number1.insert(0, width - number1.size(), '0');
    d.trkSub = prefix + number1;
    d.raDeg = *ra;
    d.decDeg = *dec;
    d.mjdUtc = number(c.fit, "t_ref_mjd").value_or(number(s.search, "t_ref_mjd").value_or(0.0));
    d.snr = number(c.fit, "snr").value_or(number(c.candidate, "snr").value_or(0.0));
    d.sigmaRaArcsec = number(c.fit, "sigma_ra_arcsec");
    d.sigmaDecArcsec = number(c.fit, "sigma_dec_arcsec");
    if (!d.sigmaRaArcsec && scale) {
      if (auto sx = number(c.fit, "sigma_x_px"), sy = number(c.fit, "sigma_y_px"); sx && sy) {
        // Pixel errors -> arcsec through the mean scale (the axes' orientation is not in the fit record).
        d.sigmaRaArcsec = *sx * *scale;
        d.sigmaDecArcsec = *sy * *scale;
      }
    }
    d.mag = number(c.fit, "mag");
    if (c.fit.is_object() && c.fit.contains("band") && c.fit["band"].is_string()) d.band = c.fit["band"];
    if (d.mjdUtc <= 0.0) {
      warnings.push_back("candidate " + std::to_string(i + 1) + " has no epoch (t_ref_mjd): not reported");
      continue;
    }
    out.push_back(d);
  }
  return out;
}

std::vector<RegionMark> regionMarks(const session::Session& s, double trackStartS, double trackEndS) {
  std::vector<RegionMark> out;
  const double fwhm = number(s.search, "psf_fwhm_px").value_or(2.5);
  for (std::size_t i = 0; i < s.candidates.size(); ++i) {
    const auto& c = s.candidates[i];
    RegionMark m;
    const bool fitted = c.fit.is_object() && c.fit.value("status", std::string{}) == "converged";
    const nlohmann::json& src = fitted ? c.fit : c.candidate;
    m.x = number(src, "x").value_or(0.0);
    m.y = number(src, "y").value_or(0.0);
    m.radiusPx = 2.0 * fwhm;
    if (auto vx = number(src, "vx_px_s"), vy = number(src, "vy_px_s"); vx && vy && trackEndS > trackStartS) {
      m.velocity = Velocity{*vx, *vy};
      m.trackStartS = trackStartS;
      m.trackEndS = trackEndS;
    }
    switch (c.label) {
      case session::Label::Real:
        m.color = "green";
        break;
      case session::Label::Artifact:
        m.color = "red";
        break;
      case session::Label::Unsure:
        m.color = "yellow";
        break;
      case session::Label::Unvetted:
        m.color = "cyan";
        break;
    }
    char buf[128];
    std::snprintf(buf, sizeof buf, "#%zu SNR %.1f %s", i + 1,
                  number(fitted ? c.fit : c.candidate, "snr").value_or(0.0), session::toString(c.label));
    m.text = buf;
    if (c.label == session::Label::Artifact) m.text += std::string(" (") + session::toString(c.reason) + ")";
    out.push_back(m);
  }
  return out;
}

}  // namespace st::report

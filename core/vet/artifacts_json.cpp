#include <numeric>

#include "st/common/error.hpp"
#include "st/vet/artifacts.hpp"

namespace st::vet {

nlohmann::json toJson(const ArtifactFlag& flag) {
  return {{"kind", toString(flag.kind)},
          {"triggered", flag.triggered},
          {"value", flag.value},
          {"evidence", flag.evidence}};
}

nlohmann::json toJson(const ArtifactParams& p) {
  return {{"leakage_half_width_px", p.leakageHalfWidthPx},
          {"leakage_min_fraction", p.leakageMinFraction},
          {"bright_star_min_snr", p.brightStarMinSnr},
          {"near_star_radius_fwhm", p.nearStarRadiusFwhm},
          {"spike_angles_deg", p.spikeAnglesDeg},
          {"spike_half_width_px", p.spikeHalfWidthPx},
          {"spike_length_px", p.spikeLengthPx},
          {"spike_min_fraction", p.spikeMinFraction},
          {"edge_margin_fwhm", p.edgeMarginFwhm},
          {"mask_radius_fwhm", p.maskRadiusFwhm},
          {"masked_min_fraction", p.maskedMinFraction},
          {"transient_top_frames", p.transientTopFrames},
          {"transient_max_share", p.transientMaxShare}};
}

ArtifactContext artifactContextFromPrepared(const nlohmann::json& j, const std::vector<double>& mjdMid,
                                            const std::string& where) {
  if (mjdMid.empty()) throw InputError("artifact checks: no frame times for '" + where + "'");
  try {
    ArtifactContext ctx;
    ctx.width = j.at("width_px").get<int>();
    ctx.height = j.at("height_px").get<int>();
    ctx.psfFwhmPx = j.at("psf").at("fwhm_px").get<double>();
    ctx.skyRate = {j.at("sky_rate_px_s").at("vx").get<double>(),
                   j.at("sky_rate_px_s").at("vy").get<double>()};
    for (const auto& s : j.at("stars")) {
      detect::Star star;
      star.x = s.at("x_px").get<double>();
      star.y = s.at("y_px").get<double>();
      star.snr = s.at("snr").get<double>();
      star.flux = s.value("flux_counts", 0.0);
      star.peak = s.value("peak_counts", 0.0);
      star.pixels = s.value("pixels", 0);
      star.saturated = s.value("saturated", false);
      star.bleedColumns = s.value("bleed_columns", std::vector<int>{});
      ctx.stars.push_back(std::move(star));
    }
    const double tRef =
        std::accumulate(mjdMid.begin(), mjdMid.end(), 0.0) / static_cast<double>(mjdMid.size());
    for (double m : mjdMid)
      ctx.timesS.push_back((m - tRef) * 86400.0);
    return ctx;
  } catch (const nlohmann::json::exception& e) {
    throw InputError("pre-processing sidecar '" + where + "': " + e.what());
  }
}

}  // namespace st::vet

#include "st/inject/truth_json.hpp"

#include "st/common/error.hpp"
#include "st/common/units.hpp"
#include "st/config.hpp"

namespace st::inject {
namespace {

nlohmann::json orNull(const std::optional<double>& v) { return v ? nlohmann::json(*v) : nlohmann::json(nullptr); }

double number(const nlohmann::json& j, const char* key, const std::string& where) {
  if (!j.contains(key)) throw InputError(where + ": missing key '" + key + "'");
  if (!j[key].is_number()) throw InputError(where + ": key '" + key + "' is not a number");
  return j[key].get<double>();
}

}  // namespace

nlohmann::json truthToJson(const InjectionRun& run, const TruthMeta& meta) {
  const InjectionPlan& plan = run.plan;
  const InjectParams& p = plan.params;
  nlohmann::json j;
  j["format"] = "synthtrack-injection-truth";
  j["version"] = 1;
  j["software"] = std::string("synthtrack ") + ST_VERSION;
  j["seed"] = p.seed;
  j["t_ref_mjd"] = plan.tRefMjd;
  j["frames"] = plan.tOffsetS.size();
  j["frame_size_px"] = {plan.width, plan.height};
  j["raw_offset_px"] = {{"x", run.geometry.offsetX}, {"y", run.geometry.offsetY}};
  j["coordinates"] =
      "x_px, y_px: 0-based pixels of the calibrated (trimmed) frame at t_ref; raw pixel = this + raw_offset_px";
  j["input_files"] = run.inputs;
  j["output_files"] = run.written;
  j["bias_files"] = meta.biasFiles;
  j["flat_files"] = meta.flatFiles;
  j["gain_e_per_adu"] = run.geometry.gainEPerAdu;
  j["em_gain"] = run.geometry.emGain;
  j["gain_source"] = meta.gainSource;
  j["plate_scale_arcsec_px"] = orNull(meta.plateScaleArcsecPerPx);
  j["zero_point_mag"] = orNull(p.zeroPointMag);
  j["clipped_pixels"] = run.clippedPixels;
  j["psf"] = {{"model", "moffat"},
              {"fwhm_px", plan.psf.fwhm()},
              {"beta", plan.psf.beta},
              {"radius_px", plan.psf.radius},
              {"source", plan.psfMeasured ? "measured" : "given"},
              {"fwhm_per_frame_px", run.field.psfFwhmPerFramePx},
              {"stamp_radius_px", plan.stampRadiusPx},
              {"trail", "sub-sampled over each frame's EXPTIME, <= 0.1 px per step"}};
  j["placement"] = {{"min_star_distance_px", p.minStarDistancePx},
                    {"edge_margin_px", p.edgeMarginPx},
                    {"min_separation_px", p.minSeparationPx},
                    {"masked_pixels", run.field.maskedPixels},
                    {"median_frame_noise", run.field.medianFrameNoise}};
  j["requested"] = {{"n", p.count},
                    {"snr_min", p.snrMin},
                    {"snr_max", p.snrMax},
                    {"rate_unit", meta.rateUnit},
                    {"rate_min", meta.rateMinAsked},
                    {"rate_max", meta.rateMaxAsked},
                    {"rate_min_px_s", p.rateMinPxS},
                    {"rate_max_px_s", p.rateMaxPxS}};
  j["snr_definition"] =
      "optimal matched-filter SNR of the whole track: sqrt(sum_n sum_q (flux P_n(q))^2 / sigma_n^2), sigma_n the "
      "frame-to-frame noise around the track (calibrated counts)";
  j["objects"] = nlohmann::json::array();
  for (const auto& o : plan.objects) {
    const double rate = std::hypot(o.vxPxS, o.vyPxS);
    j["objects"].push_back(
        {{"id", o.id},
         {"x_px", o.xPx},
         {"y_px", o.yPx},
         {"vx_px_s", o.vxPxS},
         {"vy_px_s", o.vyPxS},
         {"rate_px_s", rate},
         {"rate_deg_day", meta.plateScaleArcsecPerPx
                              ? nlohmann::json(pxPerSecToDegPerDay(rate, *meta.plateScaleArcsecPerPx))
                              : nlohmann::json(nullptr)},
         {"flux", o.flux},
         {"expected_snr", o.expectedSnr},
         {"magnitude", orNull(o.magnitude)},
         {"frame_noise", o.frameNoise},
         {"min_star_distance_px", o.minMaskDistancePx}});
  }
  return j;
}

Truth truthFromJson(const nlohmann::json& j) {
  if (!j.is_object() || !j.contains("objects") || !j["objects"].is_array())
    throw InputError("truth: no 'objects' array");
  Truth t;
  if (j.contains("t_ref_mjd") && !j["t_ref_mjd"].is_null()) t.tRefMjd = number(j, "t_ref_mjd", "truth");
  for (std::size_t k = 0; k < j["objects"].size(); ++k) {
    const auto& o = j["objects"][k];
    const std::string where = "truth object " + std::to_string(k);
    TruthObject to;
    if (!o.contains("id") || !o["id"].is_number_integer()) throw InputError(where + ": missing integer 'id'");
    to.id = o["id"].get<int>();
    to.xPx = number(o, "x_px", where);
    to.yPx = number(o, "y_px", where);
    to.vxPxS = number(o, "vx_px_s", where);
    to.vyPxS = number(o, "vy_px_s", where);
    to.expectedSnr = number(o, "expected_snr", where);
    if (o.contains("flux") && o["flux"].is_number()) to.flux = o["flux"].get<double>();
    if (o.contains("magnitude") && !o["magnitude"].is_null()) to.magnitude = number(o, "magnitude", where);
    t.objects.push_back(to);
  }
  return t;
}

}  // namespace st::inject

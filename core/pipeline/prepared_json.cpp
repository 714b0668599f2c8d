#include "st/pipeline/prepared_json.hpp"

#include <cstdio>
#include <filesystem>
#include <fstream>

#include "st/common/error.hpp"
#include "st/io/wcs.hpp"
#include "st/pipeline/prepared_cube.hpp"

namespace st::pipeline {

namespace {

const char* modelName(detect::Registration::Model m) {
  switch (m) {
    case detect::Registration::Model::Linear:
      return "linear";
    case detect::Registration::Model::PerFrame:
      return "per_frame";
    case detect::Registration::Model::Unmeasured:
      break;
  }
  return "unmeasured";
}

/// The registration's model and, per frame (cube order), the star field's measured position relative to
/// frame 0 (empty when not every frame was measured) and the offset o_n the search applies (px).
nlohmann::json registrationToJson(const Prepared& p) {
  using nlohmann::json;
  const detect::Registration& r = p.registration;
  json j = {{"model", modelName(r.model)},
            {"rate_px_s", {r.rate.vx, r.rate.vy}},
            {"residual_rms_px", r.rmsPx},
            {"residual_max_px", r.maxPx},
            {"links_measured", r.linksMeasured},
            {"significant_frames", r.significantFrames},
            {"outlier_frames", r.outlierFrames},
            {"note", r.note}};
  json position = json::array();
  for (const auto& o : r.position)
    position.push_back({o.x, o.y});
  j["position_px"] = std::move(position);
  json offsets = json::array();
  for (const auto& info : p.frames.info())
    offsets.push_back({info.offsetXPx, info.offsetYPx});
  j["offset_px"] = std::move(offsets);
  return j;
}

}  // namespace

nlohmann::json preparedToJson(const Prepared& p) {
  using nlohmann::json;
  json j;
  j["schema"] = "synthtrack.prepared";
  j["version"] = 1;
  j["frames"] = p.frames.frameCount();
  j["width_px"] = p.frames.width();
  j["height_px"] = p.frames.height();
  if (!p.frames.empty()) j["t_ref_mjd"] = p.frames.tRefMjd();
  j["sigma_n_counts"] = p.sigmaN;
  j["global_background_counts"] = p.global.mean;
  j["global_sigma_counts"] = p.global.sigma;
  j["sky_rate_px_s"] = {{"vx", p.skyRate.vx}, {"vy", p.skyRate.vy}, {"measured", p.skyRateMeasured}};
  j["registration"] = registrationToJson(p);
  j["psf"] = {{"model", "moffat"},
              {"radius_px", p.psf.radius},
              {"beta", p.psf.beta},
              {"fwhm_px", p.psf.fwhm()},
              {"fitted", p.psfFitted}};
  if (p.psfStarAt) j["psf"]["star_px"] = {p.psfStarAt->first, p.psfStarAt->second};
  j["sigma_f_counts"] = p.filtered.sigmaF;
  j["cosmic_rays"] = {{"total", p.cosmicRays}, {"per_frame", p.cosmicRaysPerFrame}};
  j["single_frame_sources"] = {{"seed_pixels_per_frame", p.singleFrame.seedsPerFrame},
                               {"zeroed_pixels_per_frame", p.singleFrame.zeroedPerFrame}};
  j["static_pixels_zeroed"] = p.staticPixelsZeroed;
  j["unmeasured_pixels_zeroed"] = p.unmeasuredPixelsZeroed;
  j["hot_pixels"] = p.hotPixels;
  j["calibration"] = {{"overscan_counts_per_frame", p.calibration.overscanLevel},
                      {"bad_pixels", p.calibration.badPixels}};
  json stars = json::array();
  for (const auto& s : p.stars) {
    json e = {{"x_px", s.x},
              {"y_px", s.y},
              {"flux_counts", s.flux},
              {"peak_counts", s.peak},
              {"snr", s.snr},
              {"filtered_snr", s.filteredSnr},
              {"pixels", s.pixels},
              {"saturated", s.saturated},
              {"bleed_columns", s.bleedColumns},
              {"motion_px", {s.motionXPx, s.motionYPx}},
              {"motion_sigma_px", s.motionSigmaPx}};
    if (p.frames.wcs) {
      try {
        const auto sky = p.frames.wcs->pixelToSky(s.x, s.y);
        e["ra_deg"] = sky.raDeg;
        e["dec_deg"] = sky.decDeg;
      } catch (const InputError&) {
      }
    }
    stars.push_back(std::move(e));
  }
  j["stars"] = std::move(stars);
  json movers = json::array();
  for (const auto& m : p.movers)
    movers.push_back({{"x_px", m.x},
                      {"y_px", m.y},
                      {"vx_px_s", m.v.vx},
                      {"vy_px_s", m.v.vy},
                      {"shift_px", m.shiftPx},
                      {"shift_sigma_px", m.shiftSigmaPx},
                      {"snr", m.snr}});
  j["moving_sources"] = std::move(movers);
  j["notes"] = p.notes;
  j["elapsed_s"] = p.elapsedS;
  return j;
}

void writePreparedSidecar(const std::string& path, const Prepared& prepared) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream f(tmp);
    if (!f) throw InputError("cannot write " + tmp);
    f << preparedToJson(prepared).dump(2) << '\n';
    if (!f) throw InputError("cannot write " + tmp);
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) throw InputError("cannot rename " + tmp + " to " + path + ": " + ec.message());
}

std::optional<std::vector<detect::MovingSource>> readPreparedMovers(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return std::nullopt;
  std::ifstream f(path);
  if (!f) throw InputError("pre-processing sidecar '" + path + "': cannot be opened");
  std::vector<detect::MovingSource> out;
  try {
    const nlohmann::json j = nlohmann::json::parse(f);
    if (!j.is_object() || !j.contains("moving_sources")) {
      throw InputError("pre-processing sidecar '" + path +
                       "': no \"moving_sources\" (not written by "
                       "synthtrack preprocess?)");
    }
    for (const auto& e : j.at("moving_sources")) {
      detect::MovingSource m;
      m.x = e.at("x_px").get<double>();
      m.y = e.at("y_px").get<double>();
      m.v = {e.at("vx_px_s").get<double>(), e.at("vy_px_s").get<double>()};
      m.shiftPx = e.value("shift_px", 0.0);
      m.shiftSigmaPx = e.value("shift_sigma_px", 0.0);
      m.snr = e.value("snr", 0.0);
      m.moving = true;
      out.push_back(m);
    }
  } catch (const nlohmann::json::exception& e) {
    throw InputError("pre-processing sidecar '" + path + "': \"moving_sources\": " + e.what());
  }
  return out;
}

PreparedBackgroundModel readPreparedBackgroundModel(const PreparedHeader& header, const FrameCube& frames,
                                                    std::vector<std::string>& notes) {
  PreparedBackgroundModel m;
  m.windows = preparedBackgroundWindows(header, frames, notes);
  if (m.windows.empty() || frames.empty()) return m;
  m.sidecar = preparedSidecarPath(cubeSource(frames));
  try {
    m.movers = readPreparedMovers(m.sidecar);
  } catch (const InputError& e) {
    m.sidecarError = e.what();
  }
  return m;
}

}  // namespace st::pipeline

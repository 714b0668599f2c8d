#include "st/sim/truth.hpp"

#include <fstream>

#include "st/common/error.hpp"

namespace st::sim {

namespace {

using nlohmann::json;

template <class T>
T get(const json& j, const char* key, const char* where) {
  if (!j.is_object() || !j.contains(key)) {
    throw InputError(std::string("truth JSON: missing key '") + key + "' in " + where);
  }
  try {
    return j.at(key).get<T>();
  } catch (const json::exception& e) {
    throw InputError(std::string("truth JSON: bad value for '") + key + "' in " + where + ": " + e.what());
  }
}

json objectJson(const TruthObject& o) {
  return {{"name", o.name},
          {"x_ref_px", o.xRefPx},
          {"y_ref_px", o.yRefPx},
          {"vx_px_s", o.vxPxPerS},
          {"vy_px_s", o.vyPxPerS},
          {"sky_vx_px_s", o.skyVxPxPerS},
          {"sky_vy_px_s", o.skyVyPxPerS},
          {"rate_deg_day", o.rateDegPerDay},
          {"frame_rate_deg_day", o.frameRateDegPerDay},
          {"magnitude", o.magnitude},
          {"photons_per_frame", o.photonsPerFrame},
          {"expected_snr", o.expectedSnr},
          {"sky_stack_snr", o.skyStackSnr},
          {"frames_inside", o.framesInside}};
}

TruthObject objectFromJson(const json& j) {
  const char* w = "objects[]";
  TruthObject o;
  o.name = get<std::string>(j, "name", w);
  o.xRefPx = get<double>(j, "x_ref_px", w);
  o.yRefPx = get<double>(j, "y_ref_px", w);
  o.vxPxPerS = get<double>(j, "vx_px_s", w);
  o.vyPxPerS = get<double>(j, "vy_px_s", w);
  o.skyVxPxPerS = get<double>(j, "sky_vx_px_s", w);
  o.skyVyPxPerS = get<double>(j, "sky_vy_px_s", w);
  o.rateDegPerDay = get<double>(j, "rate_deg_day", w);
  o.frameRateDegPerDay = get<double>(j, "frame_rate_deg_day", w);
  o.magnitude = get<double>(j, "magnitude", w);
  o.photonsPerFrame = get<double>(j, "photons_per_frame", w);
  o.expectedSnr = get<double>(j, "expected_snr", w);
  o.skyStackSnr = get<double>(j, "sky_stack_snr", w);
  o.framesInside = get<int>(j, "frames_inside", w);
  return o;
}

}  // namespace

json toJson(const Truth& t) {
  json j;
  j["format"] = "synthtrack-sim-truth";
  j["version"] = 1;
  j["preset"] = t.preset;
  j["seed"] = t.seed;
  j["width_px"] = t.width;
  j["height_px"] = t.height;
  j["frames"] = t.frames;
  j["noiseless"] = t.noiseless;
  j["t_ref_mjd"] = t.tRefMjd;
  j["frame_rate_hz"] = t.frameRateHz;
  j["exposure_s"] = t.exposureS;
  j["plate_scale_arcsec_px"] = t.plateScaleArcsecPerPx;
  j["psf"] = {{"model", "moffat"}, {"r_px", t.psfRadiusPx}, {"beta", t.psfBeta}, {"fwhm_px", t.psfFwhmPx}};
  j["sky_vx_px_s"] = t.skyVxPxPerS;
  j["sky_vy_px_s"] = t.skyVyPxPerS;
  j["gain_e_adu"] = t.gainEPerAdu;
  j["em_gain"] = t.emGain;
  j["adu_per_photon"] = t.aduPerPhoton;
  j["zero_point_photons_s"] = t.zeroPointPhotonsPerS;
  j["sky_adu"] = t.skyAdu;
  j["noise_sigma_adu"] = t.noiseSigmaAdu;
  j["noise_sigma_photons"] = t.noiseSigmaPhotons;
  j["objects"] = json::array();
  for (const auto& o : t.objects)
    j["objects"].push_back(objectJson(o));
  j["stars"] = json::array();
  for (const auto& s : t.stars) {
    j["stars"].push_back({{"x_ref_px", s.xRefPx},
                          {"y_ref_px", s.yRefPx},
                          {"magnitude", s.magnitude},
                          {"photons_per_frame", s.photonsPerFrame},
                          {"saturated", s.saturated},
                          {"spikes", s.spikes}});
  }
  j["cosmic_rays"] = json::array();
  for (const auto& c : t.cosmicRays) {
    json px = json::array();
    for (const auto& [x, y] : c.pixels)
      px.push_back({x, y});
    j["cosmic_rays"].push_back(
        {{"frame", c.frame}, {"x_px", c.xPx}, {"y_px", c.yPx}, {"peak_adu", c.peakAdu}, {"pixels_xy", px}});
  }
  j["hot_pixels"] = json::array();
  for (const auto& h : t.hotPixels)
    j["hot_pixels"].push_back({{"x_px", h.x}, {"y_px", h.y}, {"excess_adu", h.excessAdu}});
  return j;
}

Truth truthFromJson(const json& j) {
  const char* w = "truth";
  if (!j.is_object() || j.value("format", std::string()) != "synthtrack-sim-truth") {
    throw InputError("truth JSON: 'format' is not \"synthtrack-sim-truth\"");
  }
  Truth t;
  t.preset = get<std::string>(j, "preset", w);
  t.seed = get<std::uint64_t>(j, "seed", w);
  t.width = get<int>(j, "width_px", w);
  t.height = get<int>(j, "height_px", w);
  t.frames = get<int>(j, "frames", w);
  t.noiseless = get<bool>(j, "noiseless", w);
  t.tRefMjd = get<double>(j, "t_ref_mjd", w);
  t.frameRateHz = get<double>(j, "frame_rate_hz", w);
  t.exposureS = get<double>(j, "exposure_s", w);
  t.plateScaleArcsecPerPx = get<double>(j, "plate_scale_arcsec_px", w);
  const json psf = get<json>(j, "psf", w);
  t.psfRadiusPx = get<double>(psf, "r_px", "psf");
  t.psfBeta = get<double>(psf, "beta", "psf");
  t.psfFwhmPx = get<double>(psf, "fwhm_px", "psf");
  t.skyVxPxPerS = get<double>(j, "sky_vx_px_s", w);
  t.skyVyPxPerS = get<double>(j, "sky_vy_px_s", w);
  t.gainEPerAdu = get<double>(j, "gain_e_adu", w);
  t.emGain = get<double>(j, "em_gain", w);
  t.aduPerPhoton = get<double>(j, "adu_per_photon", w);
  t.zeroPointPhotonsPerS = get<double>(j, "zero_point_photons_s", w);
  t.skyAdu = get<std::vector<double>>(j, "sky_adu", w);
  t.noiseSigmaAdu = get<std::vector<double>>(j, "noise_sigma_adu", w);
  t.noiseSigmaPhotons = get<double>(j, "noise_sigma_photons", w);
  for (const auto& o : get<json>(j, "objects", w))
    t.objects.push_back(objectFromJson(o));
  for (const auto& s : get<json>(j, "stars", w)) {
    TruthStar star;
    star.xRefPx = get<double>(s, "x_ref_px", "stars[]");
    star.yRefPx = get<double>(s, "y_ref_px", "stars[]");
    star.magnitude = get<double>(s, "magnitude", "stars[]");
    star.photonsPerFrame = get<double>(s, "photons_per_frame", "stars[]");
    star.saturated = get<bool>(s, "saturated", "stars[]");
    star.spikes = get<bool>(s, "spikes", "stars[]");
    t.stars.push_back(star);
  }
  for (const auto& c : get<json>(j, "cosmic_rays", w)) {
    TruthCosmicRay cr;
    cr.frame = get<int>(c, "frame", "cosmic_rays[]");
    cr.xPx = get<double>(c, "x_px", "cosmic_rays[]");
    cr.yPx = get<double>(c, "y_px", "cosmic_rays[]");
    cr.peakAdu = get<double>(c, "peak_adu", "cosmic_rays[]");
    for (const auto& p : get<json>(c, "pixels_xy", "cosmic_rays[]")) {
      cr.pixels.emplace_back(p.at(0).get<int>(), p.at(1).get<int>());
    }
    t.cosmicRays.push_back(std::move(cr));
  }
  for (const auto& h : get<json>(j, "hot_pixels", w)) {
    t.hotPixels.push_back({get<int>(h, "x_px", "hot_pixels[]"), get<int>(h, "y_px", "hot_pixels[]"),
                           get<double>(h, "excess_adu", "hot_pixels[]")});
  }
  return t;
}

void writeTruth(const std::string& path, const Truth& truth) {
  std::ofstream out(path);
  if (!out) throw InputError("cannot write truth file '" + path + "'");
  out << toJson(truth).dump(2) << '\n';
  if (!out) throw InputError("error writing truth file '" + path + "'");
}

Truth readTruth(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError("cannot open truth file '" + path + "'");
  json j;
  try {
    in >> j;
  } catch (const json::exception& e) {
    throw InputError("truth file '" + path + "' is not valid JSON: " + e.what());
  }
  try {
    return truthFromJson(j);
  } catch (const InputError& e) {
    throw InputError("truth file '" + path + "': " + e.what());
  }
}

}  // namespace st::sim

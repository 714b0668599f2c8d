#include "st/report/search_report.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>

#include "st/common/error.hpp"
#include "st/report/candidate_json.hpp"
#include "st/search/sky_motion.hpp"

namespace st::report {

namespace {

/// `text` as one CSV field: in double quotes, inner quotes doubled, when it holds a comma, quote or newline.
std::string csvQuoted(const std::string& text) {
  if (text.find_first_of(",\"\n\r") == std::string::npos) return text;
  std::string out = "\"";
  for (const char c : text) {
    if (c == '"') out += '"';
    out += c;
  }
  return out + '"';
}

}  // namespace

nlohmann::json candidateToJson(const search::FilteredCube& cube, const search::VelocityGrid& grid,
                               const search::Candidate& c, bool crossingBrighter) {
  return toJson(candidate::measureSearch(cube, grid, c, crossingBrighter));
}

nlohmann::json searchResultToJson(const search::FilteredCube& cube, const search::SearchResult& r,
                                  const std::vector<std::string>& inputs) {
  nlohmann::json j;
  j["inputs"] = inputs;
  j["backend"] = r.backend;
  j["method"] = std::string(r.method.name());
  j["method_reason"] = r.methodReason;
  if (!r.backendNote.empty()) j["backend_note"] = r.backendNote;
  if (!r.warnings.empty()) j["warnings"] = r.warnings;
  j["t_ref_mjd"] = r.tRefMjd;
  j["frames"] = cube.frames.frameCount();
  j["sigma_f"] = cube.sigmaF;
  j["psf_fwhm_px"] = cube.psfFwhmPx;
  j["sky_rate"] = {{"vx_px_s", cube.skyRate.vx}, {"vy_px_s", cube.skyRate.vy}};
  if (cube.frames.plateScaleArcsecPerPx) j["plate_scale_arcsec_px"] = *cube.frames.plateScaleArcsecPerPx;
  j["grid"] = {{"centre_vx_px_s", r.grid.centre.vx},
               {"centre_vy_px_s", r.grid.centre.vy},
               {"step_px_s", r.grid.stepPxS},
               {"nvx", r.grid.nvx},
               {"nvy", r.grid.nvy}};
  j["trials"] = {{"nx", r.trials.nx},
                 {"ny", r.trials.ny},
                 {"nvx", r.trials.nvx},
                 {"nvy", r.trials.nvy},
                 {"total", r.trials.total()}};
  j["snr_threshold"] = r.snrThreshold;
  j["cells_above_threshold"] = r.cellsAboveThreshold;
  j["min_frames"] = r.minFrames;
  j["sidelobes_merged"] = r.sidelobesMerged;
  if (r.statisticNoise.measured())
    j["statistic_noise"] = {{"scale", r.statisticNoise.scale},
                            {"standard_error", r.statisticNoise.standardError},
                            {"mean", r.statisticNoise.mean},
                            {"cells", r.statisticNoise.cells}};
  j["elapsed_s"] = r.elapsedS;
  j["candidates"] = nlohmann::json::array();
  const std::vector<char> crossing = candidate::crossesBrighter(cube, r.grid, r.candidates);
  for (std::size_t i = 0; i < r.candidates.size(); ++i)
    j["candidates"].push_back(candidateToJson(cube, r.grid, r.candidates[i], crossing[i] != 0));
  j["static_sources"] = nlohmann::json::array();
  for (const auto& c : r.staticSources)
    j["static_sources"].push_back(candidateToJson(cube, r.grid, c));
  return j;
}

namespace {

/// json[key] as T; throws st::InputError naming the key when it is missing or of the wrong type.
template <typename T>
T required(const nlohmann::json& json, const char* key, const char* what) {
  if (!json.is_object() || !json.contains(key))
    throw InputError(std::string(what) + ": missing key '" + key + "'");
  try {
    return json.at(key).get<T>();
  } catch (const nlohmann::json::exception& e) {
    throw InputError(std::string(what) + ": key '" + key + "' has the wrong type: " + e.what());
  }
}

template <typename T>
T optionalKey(const nlohmann::json& json, const char* key, T fallback, const char* what) {
  return json.contains(key) ? required<T>(json, key, what) : fallback;
}

}  // namespace

search::Candidate candidateFromJson(const nlohmann::json& j) {
  constexpr const char* kWhat = "candidate";
  search::Candidate c;
  c.x = required<int>(j, "x", kWhat);
  c.y = required<int>(j, "y", kWhat);
  c.v = {required<double>(j, "vx_px_s", kWhat), required<double>(j, "vy_px_s", kWhat)};
  c.snr = required<double>(j, "snr", kWhat);
  c.nIn = required<int>(j, "n_frames", kWhat);
  c.fap = required<double>(j, "fap", kWhat);
  c.sum = required<double>(j, "sum", kWhat);
  c.clusterCells = required<int>(j, "cluster_cells", kWhat);
  c.ivx = required<int>(j, "ivx", kWhat);
  c.ivy = required<int>(j, "ivy", kWhat);
  return c;
}

nlohmann::json velocityMapToJson(const search::VelocityMap& map) {
  nlohmann::json snr = nlohmann::json::array();
  for (const float v : map.maxSnr) {
    if (std::isfinite(v))
      snr.push_back(static_cast<double>(v));
    else
      snr.push_back(nullptr);
  }
  return {{"nvx", map.nvx}, {"nvy", map.nvy}, {"max_snr", snr}, {"arg_x", map.argX}, {"arg_y", map.argY}};
}

search::VelocityMap velocityMapFromJson(const nlohmann::json& j) {
  constexpr const char* kWhat = "velocity map";
  search::VelocityMap map;
  map.nvx = required<int>(j, "nvx", kWhat);
  map.nvy = required<int>(j, "nvy", kWhat);
  const auto snr = required<nlohmann::json>(j, "max_snr", kWhat);
  map.argX = required<std::vector<int>>(j, "arg_x", kWhat);
  map.argY = required<std::vector<int>>(j, "arg_y", kWhat);
  const auto n =
      static_cast<std::size_t>(std::max(map.nvx, 0)) * static_cast<std::size_t>(std::max(map.nvy, 0));
  if (!snr.is_array() || snr.size() != n || map.argX.size() != n || map.argY.size() != n)
    throw InputError("velocity map: max_snr, arg_x and arg_y must hold nvx * nvy = " + std::to_string(n) +
                     " values");
  for (const auto& v : snr) {
    if (!v.is_null() && !v.is_number()) throw InputError("velocity map: max_snr holds a non-number");
    map.maxSnr.push_back(v.is_null() ? std::numeric_limits<float>::quiet_NaN()
                                     : static_cast<float>(v.get<double>()));
  }
  return map;
}

search::SearchResult searchResultFromJson(const nlohmann::json& j) {
  constexpr const char* kWhat = "search result";
  search::SearchResult r;
  const auto grid = required<nlohmann::json>(j, "grid", kWhat);
  r.grid.centre = {required<double>(grid, "centre_vx_px_s", "grid"),
                   required<double>(grid, "centre_vy_px_s", "grid")};
  r.grid.stepPxS = required<double>(grid, "step_px_s", "grid");
  r.grid.nvx = required<int>(grid, "nvx", "grid");
  r.grid.nvy = required<int>(grid, "nvy", "grid");
  const auto trials = required<nlohmann::json>(j, "trials", kWhat);
  r.trials = {required<std::int64_t>(trials, "nx", "trials"), required<std::int64_t>(trials, "ny", "trials"),
              required<std::int64_t>(trials, "nvx", "trials"),
              required<std::int64_t>(trials, "nvy", "trials")};
  r.snrThreshold = required<double>(j, "snr_threshold", kWhat);
  r.tRefMjd = required<double>(j, "t_ref_mjd", kWhat);
  r.backend = required<std::string>(j, "backend", kWhat);
  const std::string method = required<std::string>(j, "method", kWhat);
  const auto parsed = search::parseSearchMethod(method);
  if (!parsed) throw InputError(std::string(kWhat) + ": unknown \"method\" '" + method + "'");
  r.method = *parsed;
  r.methodReason = optionalKey<std::string>(j, "method_reason", std::string(), kWhat);
  r.backendNote = optionalKey<std::string>(j, "backend_note", std::string(), kWhat);
  r.warnings = optionalKey<std::vector<std::string>>(j, "warnings", {}, kWhat);
  r.elapsedS = optionalKey<double>(j, "elapsed_s", 0.0, kWhat);
  r.cellsAboveThreshold = optionalKey<std::int64_t>(j, "cells_above_threshold", 0, kWhat);
  r.minFrames = optionalKey<int>(j, "min_frames", 0, kWhat);
  r.sidelobesMerged = optionalKey<std::int64_t>(j, "sidelobes_merged", 0, kWhat);
  if (j.contains("statistic_noise")) {
    const auto& n = j["statistic_noise"];
    if (!n.is_object()) throw InputError(std::string(kWhat) + ": \"statistic_noise\" is not an object");
    r.statisticNoise.scale = required<double>(n, "scale", "statistic_noise");
    r.statisticNoise.standardError = required<double>(n, "standard_error", "statistic_noise");
    r.statisticNoise.mean = required<double>(n, "mean", "statistic_noise");
    r.statisticNoise.cells = required<int>(n, "cells", "statistic_noise");
  }
  if (j.contains("velocity_map")) r.map = velocityMapFromJson(j["velocity_map"]);
  if (j.contains("candidates")) {
    if (!j["candidates"].is_array()) throw InputError("search result: 'candidates' is not an array");
    for (const auto& c : j["candidates"])
      r.candidates.push_back(candidateFromJson(c));
  }
  if (j.contains("static_sources")) {  // written since 2026-11-26
    if (!j["static_sources"].is_array()) throw InputError("search result: 'static_sources' is not an array");
    for (const auto& c : j["static_sources"])
      r.staticSources.push_back(candidateFromJson(c));
  }
  return r;
}

void writeCandidatesCsv(const std::string& path, const nlohmann::json& result) {
  std::ofstream out(path);
  if (!out) throw InputError("cannot write '" + path + "'");
  out << "x,y,vx_px_s,vy_px_s,snr,n_frames,fap,rate_deg_day,pa_deg,cluster_cells,flags,method,method_"
         "reason\n";
  // The search method is a property of the whole run; every row carries it so a row read alone says how it
  // was found. The reason holds commas: quoted (RFC 4180).
  const std::string method = result.value("method", std::string());
  const std::string reason = csvQuoted(result.value("method_reason", std::string()));
  out.precision(10);
  auto optional = [&](const nlohmann::json& c, const char* key) {
    if (c.contains(key)) out << c[key].get<double>();
  };
  for (const auto& c : result.at("candidates")) {
    out << c["x"].get<int>() << ',' << c["y"].get<int>() << ',' << c["vx_px_s"].get<double>() << ','
        << c["vy_px_s"].get<double>() << ',' << c["snr"].get<double>() << ',' << c["n_frames"].get<int>()
        << ',' << c["fap"].get<double>() << ',';
    optional(c, "rate_deg_day");
    out << ',';
    optional(c, "pa_deg");
    out << ',' << c["cluster_cells"].get<int>() << ',';
    if (c.contains("flags")) {
      std::string joined;
      for (const auto& f : c["flags"]) {
        if (!joined.empty()) joined += ' ';
        joined += f.get<std::string>();
      }
      out << joined;
    }
    out << ',' << method << ',' << reason << '\n';
  }
  if (!out) throw InputError("error writing '" + path + "'");
}

void writeJsonFile(const std::string& path, const nlohmann::json& json) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp);
    if (!out) throw InputError("cannot write '" + tmp + "'");
    out << json.dump(2) << '\n';
    if (!out) throw InputError("error writing '" + tmp + "'");
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) throw InputError("cannot rename '" + tmp + "' to '" + path + "': " + ec.message());
}

}  // namespace st::report

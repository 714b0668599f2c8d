#include "st/report/search_report.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "st/common/error.hpp"
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
                               const search::Candidate& c) {
  nlohmann::json j;
  j["x"] = c.x;
  j["y"] = c.y;
  j["vx_px_s"] = c.v.vx;
  j["vy_px_s"] = c.v.vy;
  j["snr"] = c.snr;
  j["n_frames"] = c.nIn;
  j["fap"] = c.fap;
  j["sum"] = c.sum;
  j["cluster_cells"] = c.clusterCells;
  j["ivx"] = c.ivx;
  j["ivy"] = c.ivy;
  const Velocity onSky{c.v.vx - cube.skyRate.vx, c.v.vy - cube.skyRate.vy};
  nlohmann::json flags = nlohmann::json::array();
  // Within one grid step of the stars' motion: a static source that pre-processing did not remove.
  if (std::abs(onSky.vx) <= grid.stepPxS && std::abs(onSky.vy) <= grid.stepPxS)
    flags.push_back("at_sky_rate");
  // Fewer frames than the cube has: the track leaves the frame (edge of the field).
  if (static_cast<std::size_t>(c.nIn) < cube.frames.frameCount()) flags.push_back("partial");
  j["flags"] = flags;
  const search::SkyMotion m = search::skyMotion(cube.frames, c.x, c.y, onSky);
  if (m.rateDegPerDay) j["rate_deg_day"] = *m.rateDegPerDay;
  if (m.paDeg) j["pa_deg"] = *m.paDeg;
  return j;
}

nlohmann::json searchResultToJson(const search::FilteredCube& cube, const search::SearchResult& r,
                                  const std::vector<std::string>& inputs) {
  nlohmann::json j;
  j["inputs"] = inputs;
  j["backend"] = r.backend;
  j["method"] = r.method;
  j["method_reason"] = r.methodReason;
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
  j["elapsed_s"] = r.elapsedS;
  j["candidates"] = nlohmann::json::array();
  for (const auto& c : r.candidates)
    j["candidates"].push_back(candidateToJson(cube, r.grid, c));
  return j;
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

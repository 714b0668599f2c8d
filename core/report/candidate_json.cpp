#include "st/report/candidate_json.hpp"

#include "st/common/error.hpp"

namespace st::report {
namespace {

using nlohmann::json;

template <typename T>
T get(const json& j, const char* key, T fallback, const std::string& where) {
  if (!j.is_object() || !j.contains(key) || j[key].is_null()) return fallback;
  try {
    return j[key].get<T>();
  } catch (const json::exception&) {
    throw InputError(where + ": key '" + key + "' has the wrong type (" + j[key].dump() + ")");
  }
}

template <typename T>
T required(const json& j, const char* key, const std::string& where) {
  if (!j.is_object() || !j.contains(key)) throw InputError(where + ": missing key '" + key + "'");
  return get<T>(j, key, T{}, where);
}

template <typename T>
std::optional<T> optional(const json& j, const char* key, const std::string& where) {
  if (!j.is_object() || !j.contains(key) || j[key].is_null()) return std::nullopt;
  return get<T>(j, key, T{}, where);
}

template <typename T>
void put(json& j, const char* key, const std::optional<T>& v) {
  if (v) j[key] = *v;
}

fit::FitStatus statusFromString(const std::string& text, const std::string& where) {
  using S = fit::FitStatus;
  for (S s : {S::Converged, S::MaxIterations, S::Singular, S::Diverged, S::LeftFrame, S::NoSignal})
    if (text == fit::toString(s)) return s;
  throw InputError(where + ": unknown fit status '" + text + "'");
}

vet::ArtifactKind kindFromString(const std::string& text, const std::string& where) {
  using K = vet::ArtifactKind;
  for (K k : {K::ChargeLeakage, K::BrightStar, K::Diffraction, K::Edge, K::Masked, K::Transient,
              K::KnownObject, K::StaticSource})
    if (text == vet::toString(k)) return k;
  throw InputError(where + ": unknown artifact check '" + text + "'");
}

/// The keys both fit layouts share.
json fitCore(const candidate::FitSummary& f) {
  json j{{"status", fit::toString(f.status)},
         {"message", f.message},
         {"iterations", f.iterations},
         {"x", f.x},
         {"y", f.y},
         {"vx_px_s", f.v.vx},
         {"vy_px_s", f.v.vy},
         {"photons_per_frame", f.photonsPerFrame},
         {"snr", f.snr}};
  put(j, "t_ref_mjd", f.tRefMjd);
  put(j, "sigma_ra_arcsec", f.sigmaRaArcsec);
  put(j, "sigma_dec_arcsec", f.sigmaDecArcsec);
  put(j, "mag", f.mag);
  put(j, "band", f.band);
  return j;
}

candidate::FitSummary fitCoreFromJson(const json& j, const std::string& where) {
  if (!j.is_object()) throw InputError(where + ": the fit is not an object");
  candidate::FitSummary f;
  f.status = statusFromString(get<std::string>(j, "status", "diverged", where), where);
  f.message = get<std::string>(j, "message", "", where);
  f.iterations = get<int>(j, "iterations", 0, where);
  f.x = get<double>(j, "x", 0.0, where);
  f.y = get<double>(j, "y", 0.0, where);
  f.v = {get<double>(j, "vx_px_s", 0.0, where), get<double>(j, "vy_px_s", 0.0, where)};
  f.photonsPerFrame = get<double>(j, "photons_per_frame", 0.0, where);
  f.snr = get<double>(j, "snr", 0.0, where);
  f.tRefMjd = optional<double>(j, "t_ref_mjd", where);
  f.sigmaRaArcsec = optional<double>(j, "sigma_ra_arcsec", where);
  f.sigmaDecArcsec = optional<double>(j, "sigma_dec_arcsec", where);
  f.mag = optional<double>(j, "mag", where);
  f.band = optional<std::string>(j, "band", where);
  return f;
}

/// One segment position: segment, mjd_utc, t_offset_s, x, y, sigma_x_px, sigma_y_px, snr, and ra_deg,
/// dec_deg, sigma_ra_arcsec, sigma_dec_arcsec when it has a sky position.
json toJson(const candidate::SegmentPosition& p) {
  json j{{"segment", p.segment},
         {"mjd_utc", p.mjdUtc},
         {"t_offset_s", p.tOffsetS},
         {"x", p.x},
         {"y", p.y},
         {"sigma_x_px", p.sigmaXPx},
         {"sigma_y_px", p.sigmaYPx},
         {"snr", p.snr}};
  put(j, "ra_deg", p.raDeg);
  put(j, "dec_deg", p.decDeg);
  put(j, "sigma_ra_arcsec", p.sigmaRaArcsec);
  put(j, "sigma_dec_arcsec", p.sigmaDecArcsec);
  return j;
}

json toJson(const std::vector<candidate::SegmentPosition>& positions) {
  json list = json::array();
  for (const auto& p : positions)
    list.push_back(toJson(p));
  return list;
}

std::vector<candidate::SegmentPosition> positionsFromJson(const json& j, const char* key,
                                                          const std::string& where) {
  std::vector<candidate::SegmentPosition> out;
  if (!j.is_object() || !j.contains(key) || j[key].is_null()) return out;
  if (!j[key].is_array()) throw InputError(where + ": key '" + key + "' is not an array");
  for (const json& e : j[key]) {
    const std::string w = where + ", " + key + "[" + std::to_string(out.size()) + "]";
    candidate::SegmentPosition p;
    p.segment = required<int>(e, "segment", w);
    p.mjdUtc = required<double>(e, "mjd_utc", w);
    p.tOffsetS = get<double>(e, "t_offset_s", 0.0, w);
    p.x = required<double>(e, "x", w);
    p.y = required<double>(e, "y", w);
    p.sigmaXPx = get<double>(e, "sigma_x_px", 0.0, w);
    p.sigmaYPx = get<double>(e, "sigma_y_px", 0.0, w);
    p.snr = get<double>(e, "snr", 0.0, w);
    p.raDeg = optional<double>(e, "ra_deg", w);
    p.decDeg = optional<double>(e, "dec_deg", w);
    p.sigmaRaArcsec = optional<double>(e, "sigma_ra_arcsec", w);
    p.sigmaDecArcsec = optional<double>(e, "sigma_dec_arcsec", w);
    out.push_back(p);
  }
  return out;
}

}  // namespace

json toJson(const candidate::SearchMeasurement& s) {
  const search::Candidate& c = s.cell;
  json j{{"x", c.x},       {"y", c.y},     {"vx_px_s", c.v.vx},           {"vy_px_s", c.v.vy},
         {"snr", c.snr},   {"n_frames", c.nIn}, {"fap", c.fap},         {"sum", c.sum},
         {"ivx", c.ivx},   {"ivy", c.ivy}, {"cluster_cells", c.clusterCells}, {"flags", s.flags}};
  put(j, "rate_deg_day", s.rateDegPerDay);
  put(j, "pa_deg", s.paDeg);
  return j;
}

candidate::SearchMeasurement searchMeasurementFromJson(const json& j, const std::string& where) {
  if (!j.is_object()) throw InputError(where + ": the candidate is not an object");
  candidate::SearchMeasurement s;
  search::Candidate& c = s.cell;
  c.x = required<int>(j, "x", where);
  c.y = required<int>(j, "y", where);
  c.v = {required<double>(j, "vx_px_s", where), required<double>(j, "vy_px_s", where)};
  c.snr = required<double>(j, "snr", where);
  c.nIn = get<int>(j, "n_frames", 0, where);
  c.fap = get<double>(j, "fap", 1.0, where);
  c.sum = get<double>(j, "sum", 0.0, where);
  c.ivx = get<int>(j, "ivx", 0, where);
  c.ivy = get<int>(j, "ivy", 0, where);
  c.clusterCells = get<int>(j, "cluster_cells", 1, where);
  s.flags = get<std::vector<std::string>>(j, "flags", {}, where);
  s.rateDegPerDay = optional<double>(j, "rate_deg_day", where);
  s.paDeg = optional<double>(j, "pa_deg", where);
  return s;
}

json toFlatJson(const candidate::FitSummary& f) {
  json j = fitCore(f);
  j["sigma_x_px"] = f.sigma.xPx;
  j["sigma_y_px"] = f.sigma.yPx;
  j["sigma_vx_px_s"] = f.sigma.vxPxS;
  j["sigma_vy_px_s"] = f.sigma.vyPxS;
  j["sigma_pos_paper_px"] = f.sigma.posPaperPx;
  j["sigma_vel_paper_px_s"] = f.sigma.velPaperPxS;
  if (f.segments) {
    j["segments_flagged"] = f.segments->flagged;
    j["segment_reasons"] = f.segments->reasons;
    j["segment_snr"] = f.segments->snr;
    j["segment_positions"] = toJson(f.segments->positions);
    j["position_segments"] = f.segments->positionSegments;
  }
  if (f.sky) {
    j["ra_deg"] = f.sky->raDeg;
    j["dec_deg"] = f.sky->decDeg;
    j["rate_deg_day"] = f.sky->rateDegPerDay;
    j["rate_arcsec_min"] = f.sky->rateArcsecPerMin;
    j["pa_deg"] = f.sky->paDeg;
  }
  return j;
}

candidate::FitSummary fitFromFlatJson(const json& j, const std::string& where) {
  candidate::FitSummary f = fitCoreFromJson(j, where);
  f.sigma = {get<double>(j, "sigma_x_px", 0.0, where),         get<double>(j, "sigma_y_px", 0.0, where),
             get<double>(j, "sigma_vx_px_s", 0.0, where),      get<double>(j, "sigma_vy_px_s", 0.0, where),
             get<double>(j, "sigma_pos_paper_px", 0.0, where), get<double>(j, "sigma_vel_paper_px_s", 0.0, where)};
  if (j.contains("segments_flagged")) {
    f.segments = candidate::SegmentSummary{get<bool>(j, "segments_flagged", false, where),
                                           get<std::vector<std::string>>(j, "segment_reasons", {}, where),
                                           get<std::vector<double>>(j, "segment_snr", {}, where),
                                           positionsFromJson(j, "segment_positions", where),
                                           get<int>(j, "position_segments", 0, where)};
  }
  if (j.contains("ra_deg")) {
    f.sky = candidate::SkyPosition{get<double>(j, "ra_deg", 0.0, where), get<double>(j, "dec_deg", 0.0, where),
                                   get<double>(j, "rate_deg_day", 0.0, where),
                                   get<double>(j, "rate_arcsec_min", 0.0, where),
                                   get<double>(j, "pa_deg", 0.0, where)};
  }
  return f;
}

json toNestedJson(const candidate::FitSummary& f) {
  json j = fitCore(f);
  j["sigma"] = {{"x_px", f.sigma.xPx},           {"y_px", f.sigma.yPx},
                {"vx_px_s", f.sigma.vxPxS},      {"vy_px_s", f.sigma.vyPxS},
                {"pos_paper_px", f.sigma.posPaperPx}, {"vel_paper_px_s", f.sigma.velPaperPxS}};
  if (f.segments)
    j["segments"] = {{"flagged", f.segments->flagged},
                     {"reasons", f.segments->reasons},
                     {"snr", f.segments->snr},
                     {"positions", toJson(f.segments->positions)},
                     {"position_segments", f.segments->positionSegments}};
  if (f.sky)
    j["sky"] = {{"ra_deg", f.sky->raDeg},
                {"dec_deg", f.sky->decDeg},
                {"rate_deg_day", f.sky->rateDegPerDay},
                {"rate_arcsec_min", f.sky->rateArcsecPerMin},
                {"pa_deg", f.sky->paDeg}};
  return j;
}

candidate::FitSummary fitFromNestedJson(const json& j, const std::string& where) {
  candidate::FitSummary f = fitCoreFromJson(j, where);
  const json sigma = j.contains("sigma") ? j["sigma"] : json::object();
  const std::string w = where + ", fit";
  f.sigma = {get<double>(sigma, "x_px", 0.0, w),         get<double>(sigma, "y_px", 0.0, w),
             get<double>(sigma, "vx_px_s", 0.0, w),      get<double>(sigma, "vy_px_s", 0.0, w),
             get<double>(sigma, "pos_paper_px", 0.0, w), get<double>(sigma, "vel_paper_px_s", 0.0, w)};
  if (j.contains("segments") && j["segments"].is_object()) {
    const json& s = j["segments"];
    f.segments = candidate::SegmentSummary{
        get<bool>(s, "flagged", false, w), get<std::vector<std::string>>(s, "reasons", {}, w),
        get<std::vector<double>>(s, "snr", {}, w), positionsFromJson(s, "positions", w + ", segments"),
        get<int>(s, "position_segments", 0, w)};
  }
  if (j.contains("sky") && j["sky"].is_object()) {
    const json& s = j["sky"];
    f.sky = candidate::SkyPosition{get<double>(s, "ra_deg", 0.0, w), get<double>(s, "dec_deg", 0.0, w),
                                   get<double>(s, "rate_deg_day", 0.0, w),
                                   get<double>(s, "rate_arcsec_min", 0.0, w), get<double>(s, "pa_deg", 0.0, w)};
  }
  return f;
}

json toJson(const std::vector<vet::ArtifactFlag>& flags) {
  json list = json::array();
  for (const auto& f : flags)
    list.push_back(vet::toJson(f));
  return list;
}

std::vector<vet::ArtifactFlag> artifactsFromJson(const json& j, const std::string& where) {
  std::vector<vet::ArtifactFlag> out;
  if (j.is_null()) return out;
  if (!j.is_array()) throw InputError(where + ": \"artifacts\" is not an array");
  for (const auto& f : j) {
    vet::ArtifactFlag flag;
    flag.kind = kindFromString(get<std::string>(f, "kind", "", where), where);
    flag.triggered = get<bool>(f, "triggered", false, where);
    flag.value = get<double>(f, "value", 0.0, where);
    flag.evidence = get<std::string>(f, "evidence", "", where);
    out.push_back(std::move(flag));
  }
  return out;
}

json toCandidatesFileJson(const candidate::CandidateMeasurement& c) {
  json o = toJson(c.search);
  if (c.fit) o["fit"] = toFlatJson(*c.fit);
  o["label"] = candidate::toString(c.label);
  o["reason"] = candidate::toString(c.reason);
  o["note"] = c.note;
  o["artifacts"] = toJson(c.artifacts);
  return o;
}

candidate::CandidateMeasurement fromCandidatesFileJson(const json& j, const std::string& where) {
  candidate::CandidateMeasurement c;
  c.search = searchMeasurementFromJson(j, where);
  if (j.contains("fit") && !j["fit"].is_null()) c.fit = fitFromFlatJson(j["fit"], where + ", fit");
  c.label = candidate::labelFromString(get<std::string>(j, "label", "unvetted", where));
  c.reason = candidate::reasonFromString(get<std::string>(j, "reason", "", where));
  c.note = get<std::string>(j, "note", "", where);
  if (j.contains("artifacts")) c.artifacts = artifactsFromJson(j["artifacts"], where);
  return c;
}

}  // namespace st::report

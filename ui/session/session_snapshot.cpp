#include "session_snapshot.hpp"

#include "st/common/error.hpp"
#include "st/report/search_report.hpp"

namespace st::ui {
namespace {

using nlohmann::json;

constexpr std::pair<VelocityUnit, const char*> kUnits[] = {{VelocityUnit::PxPerS, "px_s"},
                                                           {VelocityUnit::ArcsecPerMin, "arcsec_min"},
                                                           {VelocityUnit::DegPerDay, "deg_day"}};

json gridToJson(const search::VelocityGrid& g) {
  return {{"centre_vx_px_s", g.centre.vx},
          {"centre_vy_px_s", g.centre.vy},
          {"step_px_s", g.stepPxS},
          {"nvx", g.nvx},
          {"nvy", g.nvy}};
}

/// The key a stage is stored under: its stable key (format 3), the name for a stage without one (test fakes).
const std::string& storedKey(const StageSpec& stage) { return stage.key.empty() ? stage.name : stage.key; }

json stagesToJson(const std::vector<StageSpec>& stages) {
  json out = json::object();
  for (const auto& stage : stages) {
    json params = json::object();
    for (const auto& p : stage.params)
      params[p.key] = p.value;
    json& saved = out[storedKey(stage)];
    saved = {{"enabled", stage.enabled}, {"parameters", params}};
    if (!stage.files.empty()) {  // absent in sessions written before the calibration pickers: none
      json files = json::object();
      for (const auto& f : stage.files)
        files[f.key] = f.paths;
      saved["files"] = files;
    }
  }
  return out;
}

json searchParametersToJson(const SessionParameters& p) {
  return {{"grid", gridToJson(p.grid)},
          {"snr_threshold", p.search.snrThreshold},
          {"target_fap", p.search.targetFap ? json(*p.search.targetFap) : json(nullptr)},
          {"max_candidates", p.search.maxCandidates},
          {"min_frame_fraction", p.search.minFrameFraction},
          {"method", std::string(p.search.method.name())},
          {"backend", toString(p.backend)}};
}

/// `json[key]` as T when present, else `fallback`; throws st::InputError naming the key when mistyped.
template <typename T>
T valueOr(const json& j, const char* key, T fallback, const std::string& where) {
  if (!j.is_object() || !j.contains(key) || j[key].is_null()) return fallback;
  try {
    return j[key].get<T>();
  } catch (const json::exception&) {
    throw InputError(where + ": parameter '" + key + "' has the wrong type");
  }
}

std::vector<StageSpec> restoreStages(const json& saved, std::vector<StageSpec> stages,
                                     const std::string& where) {
  if (!saved.is_object()) return stages;
  for (auto& stage : stages) {
    // Format 3 stores the stable key; format 2 stored the display name (kept in formerKeys).
    std::vector<std::string> keys{storedKey(stage), stage.name};
    keys.insert(keys.end(), stage.formerKeys.begin(), stage.formerKeys.end());
    const json* found = nullptr;
    for (const std::string& key : keys)
      if (!found && saved.contains(key)) found = &saved.at(key);
    if (!found) continue;
    const json& s = *found;
    stage.enabled = !stage.optional || valueOr<bool>(s, "enabled", stage.enabled, where);
    const json params = s.is_object() && s.contains("parameters") ? s["parameters"] : json::object();
    for (auto& p : stage.params)
      p.value = valueOr<double>(params, p.key.c_str(), p.value, where);
    const json files = s.is_object() && s.contains("files") ? s["files"] : json::object();
    for (auto& f : stage.files)
      f.paths = valueOr<std::vector<std::string>>(files, f.key.c_str(), f.paths, where);
  }
  return stages;
}

search::VelocityGrid gridFromJson(const json& j, const std::string& where) {
  search::VelocityGrid g;
  g.centre = {valueOr<double>(j, "centre_vx_px_s", 0.0, where),
              valueOr<double>(j, "centre_vy_px_s", 0.0, where)};
  g.stepPxS = valueOr<double>(j, "step_px_s", 0.0, where);
  g.nvx = valueOr<int>(j, "nvx", 0, where);
  g.nvy = valueOr<int>(j, "nvy", 0, where);
  return g;
}

void restoreSearchParameters(const json& s, SessionParameters& p, const std::string& where) {
  if (!s.is_object()) return;
  if (s.contains("grid")) p.grid = gridFromJson(s["grid"], where);
  p.search.snrThreshold = valueOr<double>(s, "snr_threshold", p.search.snrThreshold, where);
  if (s.contains("target_fap") && !s["target_fap"].is_null())
    p.search.targetFap = valueOr<double>(s, "target_fap", 0.0, where);
  p.search.maxCandidates = valueOr<std::size_t>(s, "max_candidates", p.search.maxCandidates, where);
  p.search.minFrameFraction = valueOr<double>(s, "min_frame_fraction", p.search.minFrameFraction, where);
  const std::string method = valueOr<std::string>(s, "method", std::string(p.search.method.name()), where);
  const auto parsed = search::parseSearchMethod(method);
  if (!parsed)
    throw InputError(where + ": parameter 'method' is '" + method + "' (expected auto, exact or tree)");
  p.search.method = *parsed;
  p.backend = backendKindFromString(valueOr<std::string>(s, "backend", "auto", where));
}

}  // namespace

search::SearchParams defaultPanelSearchParams() {
  search::SearchParams p;
  p.method = search::SearchMethod::Auto;
  return p;
}

const char* toString(BackendKind kind) noexcept {
  switch (kind) {
    case BackendKind::Cpu:
      return "cpu";
    case BackendKind::Gpu:
      return "gpu";
    default:
      return "auto";
  }
}

BackendKind backendKindFromString(const std::string& text) noexcept {
  if (text == "cpu") return BackendKind::Cpu;
  if (text == "gpu") return BackendKind::Gpu;
  return BackendKind::Auto;
}

session::Session makeSession(const Observation& obs, const std::vector<std::string>& inputs,
                             const SessionParameters& parameters, const json& settings) {
  session::Session s;
  s.inputs = inputs;
  s.settings = settings.is_object() ? settings : json::object();
  s.parameters["observation"] = {{"demo", parameters.demo}, {"label", obs.label().toStdString()}};
  if (parameters.demoAutosave) s.parameters["observation"]["demo_autosave"] = true;
  s.parameters["preprocess"] = stagesToJson(parameters.stages);
  s.parameters["search"] = searchParametersToJson(parameters);
  const char* unit = "px_s";
  for (const auto& [u, key] : kUnits)
    if (u == obs.unit()) unit = key;
  s.parameters["view"] = {{"selected", obs.selected() ? json(*obs.selected()) : json(nullptr)},
                          {"velocity_unit", unit}};
  if (const auto& solved = obs.solvedWcs(); solved && solved->wcs) {
    json cards = json::array();
    for (const FitsCard& c : solved->wcs->toHeader().cards)
      cards.push_back({{"key", c.key}, {"value", c.value}, {"is_string", c.isString}});
    s.parameters["plate_solve"] = {{"scale_arcsec_px", solved->plateScaleArcsecPerPx}, {"wcs_cards", cards}};
  }
  const auto& result = obs.result();
  if (!result) return s;
  // The cube gives the sky rate, frame count and WCS the candidate keys need; without one (never in the app,
  // a search needs it) the keys that depend on it are left out.
  const auto& prepared = obs.prepared();
  const search::FilteredCube empty;
  const search::FilteredCube& cube = prepared && prepared->filtered ? *prepared->filtered : empty;
  s.search = report::searchResultToJson(cube, *result, inputs);
  s.search.erase("candidates");
  s.search["velocity_map"] = report::velocityMapToJson(result->map);
  const auto& states = obs.candidateStates();
  const std::vector<char> crossing = candidate::crossesBrighter(cube, result->grid, result->candidates);
  for (std::size_t i = 0; i < result->candidates.size(); ++i) {
    session::CandidateState state = i < states.size() ? states[i] : session::CandidateState{};
    state.search = candidate::measureSearch(cube, result->grid, result->candidates[i], crossing[i] != 0);
    s.candidates.push_back(std::move(state));
  }
  return s;
}

namespace {

/// "plate_solve" of a session file back to a WCS; throws st::InputError naming the file and the key at fault.
Observation::SolvedWcs restoreSolvedWcs(const json& saved, const std::string& where) {
  const std::string at = where + ": parameters.plate_solve";
  if (!saved.is_object() || !saved.contains("wcs_cards") || !saved["wcs_cards"].is_array())
    throw InputError(at + ": expected an object with a 'wcs_cards' array");
  FitsHeader header;
  for (const json& c : saved["wcs_cards"]) {
    if (!c.is_object() || !c.contains("key") || !c["key"].is_string() || !c.contains("value") ||
        !c["value"].is_string())
      throw InputError(at + ".wcs_cards: each card needs a string 'key' and 'value'");
    FitsCard card;
    card.key = c["key"].get<std::string>();
    card.value = c["value"].get<std::string>();
    card.isString = c.value("is_string", false);
    header.cards.push_back(std::move(card));
  }
  std::vector<std::string> warnings;
  Observation::SolvedWcs solved;
  solved.wcs = Wcs::fromHeader(header, &warnings);
  if (!solved.wcs)
    throw InputError(at + ".wcs_cards: not a usable WCS" + (warnings.empty() ? "" : " (" + warnings[0] + ")"));
  solved.plateScaleArcsecPerPx = valueOr<double>(saved, "scale_arcsec_px", 0.0, at);
  if (!(solved.plateScaleArcsecPerPx > 0.0))
    throw InputError(at + ".scale_arcsec_px: expected a plate scale > 0 arcsec/px");
  return solved;
}

}  // namespace

SessionSnapshot restoreSnapshot(const session::Session& session, const std::vector<StageSpec>& defaults,
                                const std::string& where) {
  SessionSnapshot snap;
  snap.inputs = session.inputs;
  const json& p = session.parameters;
  const json observation = p.contains("observation") ? p["observation"] : json::object();
  snap.parameters.demo = valueOr<bool>(observation, "demo", false, where);
  snap.parameters.demoAutosave = valueOr<bool>(observation, "demo_autosave", false, where);
  snap.label = QString::fromStdString(valueOr<std::string>(observation, "label", "", where));
  snap.parameters.stages =
      restoreStages(p.contains("preprocess") ? p["preprocess"] : json(), defaults, where);
  restoreSearchParameters(p.contains("search") ? p["search"] : json(), snap.parameters, where);
  if (p.contains("plate_solve")) snap.solvedWcs = restoreSolvedWcs(p["plate_solve"], where);
  const json view = p.contains("view") ? p["view"] : json::object();
  const std::string unit = valueOr<std::string>(view, "velocity_unit", "px_s", where);
  for (const auto& [u, key] : kUnits)
    if (unit == key) {
      snap.unit = u;
      snap.unitSaved = view.contains("velocity_unit");
    }
  if (!session.search.is_object() || session.search.empty()) {
    if (!session.candidates.empty())
      throw InputError(where + ": candidates without a search result (the 'search' member is empty)");
    return snap;
  }
  search::SearchResult result;
  try {
    result = report::searchResultFromJson(session.search);
  } catch (const InputError& e) {
    throw InputError(where + ": " + e.what());
  }
  for (const auto& state : session.candidates)
    result.candidates.push_back(state.search.cell);
  snap.states = session.candidates;
  for (auto& state : snap.states)
    state.search = {};
  const int selected = valueOr<int>(view, "selected", -1, where);
  if (selected >= 0 && selected < static_cast<int>(result.candidates.size())) snap.selected = selected;
  snap.parameters.grid = snap.parameters.grid.count() > 0 ? snap.parameters.grid : result.grid;
  snap.result = std::make_shared<const search::SearchResult>(std::move(result));
  return snap;
}

}  // namespace st::ui

#pragma once
// The GUI's state as a session file's content and back (st::session::Session, issue 8 §6). makeSession()
// records what a person did: inputs, every pre-processing and search parameter, the search result (grid,
// velocity map, trial counts, backend and method used) and every candidate with its vetting state (label,
// note, accepted fit, artifact flags). restoreSnapshot() is the inverse: what reopening needs to rebuild the
// same state without searching again (the inputs are reloaded and pre-processed with the saved parameters,
// then the saved result is put back).
//
// Layout of Session::parameters (stable keys, units in the names):
//   "observation": {"demo": bool, "label": string, "demo_autosave": bool (absent = false)}
//   "preprocess":  {"<stage name>": {"enabled": bool, "parameters": {"<key>": number, ...}}, ...}
//   "search":      {"grid": {centre_vx_px_s, centre_vy_px_s, step_px_s, nvx, nvy}, "snr_threshold",
//                   "target_fap" (null when the threshold is by SNR), "max_candidates", "min_frame_fraction",
//                   "method" ("auto" | "exact" | "tree"), "backend" ("auto" | "cpu" | "gpu")}
//   "view":        {"selected": 0-based candidate index or null, "velocity_unit": "px_s" | "arcsec_min" |
//   "deg_day"}
//   "plate_solve": only when the frames had no WCS and one was plate-solved in the GUI (Observation::
//                  solvedWcs): {"scale_arcsec_px": number, "wcs_cards": [{"key", "value", "is_string"}, ...]}
//                  (Wcs::toHeader()'s cards, mapping the first loaded frame's pixels); reopening attaches it
//                  to the reloaded frames before they are pre-processed.
// Every key is optional on reading: a file from an older build that lacks one (e.g. "method", "backend",
// "demo_autosave") loads with the GUI's default for it (SessionParameters' defaults: SNR 7, method auto,
// backend auto); keys are only ever added, so Session::version does not change for them (an older build
// ignores a key it does not know). Session::search is report::searchResultToJson() without "candidates", plus
// "velocity_map" (report::velocityMapToJson). Each CandidateState::search is candidate::measureSearch().
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core_services.hpp"
#include "observation.hpp"
#include "st/search/types.hpp"
#include "st/session/session.hpp"

namespace st::ui {

/// The search panel's settings before anything is changed: search::SearchParams with method "auto".
[[nodiscard]] search::SearchParams defaultPanelSearchParams();

/// What a session records besides the Observation: the panels' settings at the time of the save.
struct SessionParameters {
  std::vector<StageSpec> stages;  ///< pre-processing as set (ProcessingPanel::stages())
  search::VelocityGrid grid;      ///< the search panel's grid (the result keeps the grid it used)
  search::SearchParams search = defaultPanelSearchParams();  ///< thresholds, method (SearchPanel::params())
  BackendKind backend = BackendKind::Auto;
  bool demo = false;  ///< the observation is the simulated demo (no input files)
  /// The file is an autosave of the demo in the application's own folder, which later demo runs may prune
  /// (SessionController); never set for a file a person saved (Save session as…).
  bool demoAutosave = false;
};

/// The session of the GUI's current state. `inputs` are the frame files as opened (absolute paths);
/// `settings` the report settings (station code, observers, ...), kept as given. Candidates are written with
/// candidate::measureSearch() against the pre-processed cube (sky rates and flags included) and carry the
/// Observation's vetting states. Session::changes is 0; SessionStore::save() counts.
[[nodiscard]] session::Session makeSession(const Observation& observation,
                                           const std::vector<std::string>& inputs,
                                           const SessionParameters& parameters,
                                           const nlohmann::json& settings = nlohmann::json::object());

/// What reopening a session restores.
struct SessionSnapshot {
  std::vector<std::string> inputs;
  QString label;                 ///< the observation's label ("" when not recorded)
  SessionParameters parameters;  ///< stages = the defaults given, with the saved values applied
  /// The saved search result (candidates rebuilt with report::candidateFromJson); null when the session has
  /// no search yet.
  std::shared_ptr<const search::SearchResult> result;
  /// One per candidate of `result`, in its order; their `search` member is cleared (the Observation keeps
  /// search::Candidate, see Observation::candidateStates()).
  std::vector<session::CandidateState> states;
  std::optional<int> selected;  ///< 0-based, within range of the result
  VelocityUnit unit = VelocityUnit::PxPerS;
  bool unitSaved = false;  ///< the file names the unit (else the window keeps its own default)
  /// The plate-solved WCS of frames without one ("plate_solve"); empty when the session has none.
  std::optional<Observation::SolvedWcs> solvedWcs;
};

/// The inverse of makeSession(). `defaults` are the pipeline's stages (CoreServices::preprocessStages): a
/// saved stage or parameter they do not know is ignored, one the session lacks keeps its default (sessions
/// from an older build stay readable). Throws st::InputError naming the key at fault (`where` names the
/// file).
[[nodiscard]] SessionSnapshot restoreSnapshot(const session::Session& session,
                                              const std::vector<StageSpec>& defaults,
                                              const std::string& where);

/// The stable key of a backend choice ("auto", "cpu", "gpu") and back (unknown text gives Auto).
[[nodiscard]] const char* toString(BackendKind kind) noexcept;
[[nodiscard]] BackendKind backendKindFromString(const std::string& text) noexcept;

}  // namespace st::ui

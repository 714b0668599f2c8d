#pragma once
// The persisted state of one analysis (ARCHITECTURE.md, "Persistence"; issue 8 §6): inputs, every parameter,
// candidates, fits, vetting labels and notes, in a versioned JSON file. SessionStore writes it atomically
// (temporary file in the same folder, fsync, rename, fsync of the folder) after every change a person makes,
// so a crash (kill -9 while labelling) loses at most the change being written. A file from a newer format
// version, or one that cannot be parsed, is never overwritten silently: it is copied aside and the error
// names the copy.
//
// Candidates are typed records (st::candidate::CandidateMeasurement); parameters, the search summary and the
// report settings are kept as the JSON objects their stages write. A round trip through the file is exact.
#include <cstdint>
#include <cstddef>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "st/candidate/candidate_measurement.hpp"

namespace st::session {

/// Format version written by this build. Files with a larger number are refused (with a backup copy); older
/// ones are migrated on reading (format 1, up to 2026-11-25: each candidate's "candidate" object and a flat
/// "fit"; format 2: "search" and a fit with nested "sigma", "segments" and "sky", candidate_json.hpp;
/// format 3, from 2026-11-27: the same candidates, and parameters.preprocess keyed by the stages' stable
/// keys (preprocess_settings.hpp) where format 2 keyed them by display label; the GUI reads both).
inline constexpr int kSessionFormatVersion = 3;
inline constexpr const char* kSessionFormatName = "synthtrack-session";

using candidate::ArtifactReason;
using candidate::Label;
using candidate::labelFromString;
using candidate::reasonFromString;
using candidate::toString;

/// One candidate of the session: the typed record (candidate_measurement.hpp).
using CandidateState = candidate::CandidateMeasurement;

struct Session {
  int version = kSessionFormatVersion;
  std::vector<std::string> inputs;                       ///< frame files, as given
  nlohmann::json parameters = nlohmann::json::object();  ///< every parameter of every stage, by stage name
  nlohmann::json search = nlohmann::json::object();      ///< the search result without its candidates
  std::vector<CandidateState> candidates;
  nlohmann::json settings = nlohmann::json::object();  ///< report settings (station code, observers, ...)
  std::string notes;                                   ///< free text for the whole session
  std::int64_t changes = 0;  ///< number of changes saved so far (increments with every save)
  friend bool operator==(const Session&, const Session&) = default;
};

/// A session from a search result object (searchResultToJson / `synthtrack-cli search --json`, or the
/// candidates file the reports write): inputs from its "inputs", candidates (report::fromCandidatesFileJson:
/// the search keys, "fit", and "label", "reason", "note", "artifacts" when present), the rest as `search`.
[[nodiscard]] Session fromSearchJson(const nlohmann::json& result);

[[nodiscard]] nlohmann::json toJson(const Session& session);
/// Reads format 1 (migrating it), 2 and 3. Throws st::InputError naming the key at fault (`where` names the
/// file).
[[nodiscard]] Session fromJson(const nlohmann::json& json, const std::string& where);

/// The session file of one analysis.
class SessionStore {
 public:
  explicit SessionStore(std::string path) : m_path(std::move(path)) {}
  [[nodiscard]] const std::string& path() const noexcept { return m_path; }

  /// Reads the session. A leftover temporary file from an interrupted save is ignored (the file itself holds
  /// the last complete save; the temporary file is left alone, another process may be writing it). Throws
  /// st::InputError when the file is missing; when it is not valid JSON or not a session, or was written by a
  /// newer format version, the file is first copied to NAME.corrupt-<UTC timestamp>.json (or NAME.newer-<UTC
  /// timestamp>.json) beside it and the message names the problem and the copy. The original is left in
  /// place.
  [[nodiscard]] Session load() const;
  /// True when the file exists.
  [[nodiscard]] bool exists() const;
  /// Writes `session` atomically: NAME.tmp-<pid> in the same folder, flushed with fsync, renamed over the
  /// file, folder fsync'ed. Increments session.changes first. Throws st::InputError naming the path.
  void save(Session& session) const;
  /// The temporary file save() writes (for tests that simulate an interrupted save).
  [[nodiscard]] std::string tempPath() const;

 private:
  std::string m_path;
};

/// Applies one change and saves at once (the autosave every GUI action and CLI edit goes through). Without a
/// store (nullopt) the changes stay in memory (a report run without a session file).
class SessionEditor {
 public:
  SessionEditor(std::optional<SessionStore> store, Session session)
      : m_store(std::move(store)), m_session(std::move(session)) {}
  [[nodiscard]] const Session& session() const noexcept { return m_session; }
  /// Throws st::InputError for an index out of range, or a reason given with a label other than Artifact.
  void setLabel(std::size_t candidate, Label label, ArtifactReason reason = ArtifactReason::None);
  void setNote(std::size_t candidate, std::string note);
  void setFit(std::size_t candidate, std::optional<candidate::FitSummary> fit);
  void setArtifacts(std::size_t candidate, std::vector<vet::ArtifactFlag> flags);
  void setParameters(const std::string& stage, nlohmann::json parameters);
  void setSettings(nlohmann::json settings);
  void setSessionNotes(std::string notes);
  /// Saves the current state (e.g. after creating the session); nothing without a store.
  void save() {
    if (m_store) m_store->save(m_session);
  }

 private:
  CandidateState& at(std::size_t candidate);
  std::optional<SessionStore> m_store;
  Session m_session;
};

}  // namespace st::session

#pragma once
// The persisted state of one analysis (ARCHITECTURE.md, "Persistence"; issue 8 §6): inputs, every parameter,
// candidates, fits, vetting labels and notes, in a versioned JSON file. SessionStore writes it atomically
// (temporary file in the same folder, fsync, rename, fsync of the folder) after every change a person makes,
// so a crash (kill -9 while labelling) loses at most the change being written. A file from a newer format
// version, or one that cannot be parsed, is never overwritten silently: it is copied aside and the error
// names the copy.
//
// Candidates, fits and parameters are kept as the JSON objects the other stages write (search_report.hpp
// keys, the fit's keys), so nothing is lost between versions of those stages and a round trip is exact.
#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

namespace st::session {

/// Format version written by this build. Files with a larger number are refused (with a backup copy).
inline constexpr int kSessionFormatVersion = 1;
inline constexpr const char* kSessionFormatName = "synthtrack-session";

enum class Label { Unvetted, Real, Artifact, Unsure };
enum class ArtifactReason { None, ChargeLeakage, Diffraction, CosmicRay, Ghost, Other };

/// Stable keys: "unvetted", "real", "artifact", "unsure"; "", "charge_leakage", "diffraction", "cosmic_ray",
/// "ghost", "other".
[[nodiscard]] const char* toString(Label label) noexcept;
[[nodiscard]] const char* toString(ArtifactReason reason) noexcept;
/// Throws st::InputError naming the text when it is not one of the keys above.
[[nodiscard]] Label labelFromString(const std::string& text);
[[nodiscard]] ArtifactReason reasonFromString(const std::string& text);

struct CandidateState {
  nlohmann::json candidate = nlohmann::json::object();  ///< the search's candidate object (search_report.hpp)
  nlohmann::json fit;                                   ///< the accepted co-moving fit (null when none)
  nlohmann::json artifacts = nlohmann::json::array();   ///< artifact flags: kind, triggered, value, evidence
  Label label = Label::Unvetted;
  ArtifactReason reason = ArtifactReason::None;  ///< only for Label::Artifact
  std::string note;
  friend bool operator==(const CandidateState&, const CandidateState&) = default;
};

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

/// A session from a search result object (searchResultToJson / `synthtrack-cli search --json`): inputs from
/// its "inputs", candidates (with a "fit" member moved to CandidateState::fit), the rest as `search`.
[[nodiscard]] Session fromSearchJson(const nlohmann::json& result);

[[nodiscard]] nlohmann::json toJson(const Session& session);
/// Throws st::InputError naming the key at fault (`where` names the file).
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
  void setFit(std::size_t candidate, nlohmann::json fit);
  void setArtifacts(std::size_t candidate, nlohmann::json flags);
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

#pragma once
// The session of the main window (issue 8 §6): which file the current analysis is saved to, and an autosave
// after every change of the Observation (new observation, pre-processing, result, a candidate's label, note,
// fit or artifact flags, the selection, the velocity unit). The state is gathered on the GUI thread
// (makeSession) and written by SessionAutosaver's worker. The file of a new analysis is chosen by
// defaultSessionPath() (a per-user folder, not the data folder); an existing file is never overwritten by a
// new analysis (the next free name is used), nor are vetted candidates by a new pre-processing run or search
// (the analysis goes on in a new file).
#include <QObject>
#include <QString>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "observation.hpp"
#include "session_autosaver.hpp"
#include "session_lock.hpp"
#include "session_snapshot.hpp"

namespace st::ui {

/// The folder of new sessions: `folder`, or QStandardPaths::AppDataLocation + "/sessions" when it is empty.
/// Sessions are not written into the data folder (shared or archived frames, other users' nights).
[[nodiscard]] QString sessionFolder(const QString& folder = {});
/// Where a new analysis of `inputs` keeps its session: sessionFolder(folder) + "/NAME-HASH.synthtrack-session
/// .json", NAME = the first input's file name without its FITS extensions (or the folder's name), HASH = 8 hex
/// digits of the SHA-1 of the inputs' absolute paths; the demo's is "demo.synthtrack-session.json" there (a
/// new demo run prunes the older ones, pruneDemoAutosaves()). The folder is created.
[[nodiscard]] QString defaultSessionPath(const std::vector<std::string>& inputs, bool demo,
                                         const QString& folder = {});
/// Where sessions were written before they left the data folder: NAME.synthtrack-session.json beside the
/// first input ("" without inputs). A file there is still offered when the inputs are opened again, and
/// opens like any session.
[[nodiscard]] QString legacySessionPath(const std::vector<std::string>& inputs);
/// `path` when it is free, else the first of NAME-2.EXT, NAME-3.EXT, ... that is. A name is taken when its
/// session file or its lock file is there: a window that has just locked a fresh name, and not yet written
/// it, holds it.
[[nodiscard]] QString freeSessionPath(const QString& path);

/// Demo autosaves kept in the application's folder, the one being written included.
inline constexpr int kDemoAutosavesKept = 5;

/// Removes old demo autosaves from `folder` so that each `--demo` run does not leave one more file: of the
/// files named demo.synthtrack-session.json / demo.synthtrack-session-N.json whose content says it is a demo
/// autosave ("demo_autosave": true, SessionParameters::demoAutosave), not locked by a window, and other than
/// `current`, the newest `keep - 1` (by modification time) stay and the others are deleted. A file a person
/// saved (Save session as…) never carries the mark, and a file that cannot be read is kept. Returns the
/// paths deleted.
QStringList pruneDemoAutosaves(const QString& folder, const QString& current, int keep = kDemoAutosavesKept);

class SessionController : public QObject {
  Q_OBJECT
 public:
  /// `parameters` gives the panels' settings at the time of a save (called on the GUI thread).
  SessionController(Observation* observation, std::function<SessionParameters()> parameters,
                    QObject* parent = nullptr);

  /// Writes what is queued before the file's lock is released.
  ~SessionController() override;

  [[nodiscard]] SessionAutosaver* autosaver() const noexcept { return m_saver; }
  /// The session file changes go to ("" before the first observation).
  [[nodiscard]] const QString& path() const noexcept { return m_path; }
  [[nodiscard]] const std::vector<std::string>& inputs() const noexcept { return m_inputs; }
  [[nodiscard]] bool demo() const noexcept { return m_demo; }
  /// Report settings kept in the session (station code, observers, ...); setting them saves.
  [[nodiscard]] const nlohmann::json& settings() const noexcept { return m_settings; }
  void setSettings(nlohmann::json settings);

  /// An observation is being opened: when its frames arrive (Observation::rawChanged) a new session starts
  /// in `path` (defaultSessionPath() when empty), or in the next free name when a file is already there
  /// (notice() says so).
  void prepareNew(std::vector<std::string> inputs, bool demo, const QString& path = {});
  /// Continue in an opened session file (no save until the next change), counting on from `changes`.
  /// `demoAutosave`: the file is a demo autosave (SessionParameters::demoAutosave, kept as it is).
  void adopt(const QString& path, std::vector<std::string> inputs, bool demo, std::int64_t changes,
             nlohmann::json settings, bool demoAutosave = false);
  /// Save the current state to `path` from now on (File > Save session as…; never pruned).
  void saveAs(const QString& path);
  /// `result` (about to be set on the Observation) continues the current one (candidates added to it, every
  /// earlier candidate and its state kept): it is saved to the same file, never forked as a new search is.
  void continueWith(const search::SearchResult* result) { m_sessionResult = result; }
  /// While restoring a session, the intermediate states are not saved.
  void setSuspended(bool suspended) { m_suspended = suspended; }
  /// Builds the current session and queues it (nothing without a path or while suspended).
  void requestSave();
  /// The session as it would be saved now.
  [[nodiscard]] session::Session currentSession() const;

  /// A session file opened while another window or process holds its lock (SessionLock): shown, not saved.
  struct ReadOnly {
    QString path;           ///< the file, as it was asked for
    QString holder;         ///< who holds it: "synthtrack pid 1234 on host node7" (SessionLock::Holder)
    int unsavedChanges = 0; ///< labels, notes, fits and flags changed here since, which no file has
  };
  /// Set while the window shows a session read-only (the main window's banner); empty otherwise.
  [[nodiscard]] const std::optional<ReadOnly>& readOnly() const noexcept { return m_readOnly; }

 signals:
  /// Text for the status bar: the path and the state of the last save; `error` for a failed save.
  void statusChanged(const QString& text, const QString& tooltip, bool error);
  /// Changes go to a new file from now on (a new analysis, an opened session, Save as…).
  void pathChanged(const QString& path);
  /// Something the person should know, for the status bar (e.g. an earlier session of these inputs kept).
  void notice(const QString& text);
  /// A save failed for the first time after a success (the message names the path).
  void saveFailed(const QString& message);
  /// readOnly() changed: entered, left (another file, Save as…), or one more unsaved change.
  void readOnlyChanged();

 private:
  /// Starts the session prepared by prepareNew() (path, inputs, change count).
  void startNext();
  /// Changes go to `path` from now on, counting on from `changes`; false (and no file) when another window
  /// or process holds the file's lock (saveFailed() says so).
  bool setPath(const QString& path, std::int64_t changes);
  /// Locks the first free name from `preferred` on (freeSessionPath()) and returns it: two windows or
  /// processes starting a session of the same observation at once can see the same free name, and the one
  /// that does not get its lock takes the next, not that file read-only.
  QString lockFreshPath(const QString& preferred);
  /// Leaves the current file as it is and continues in the next free name.
  void forkFile();
  void onSaved(const QString& path, qint64 changes, double ms);
  void onFailed(const QString& path, const QString& message);

  Observation* m_obs;
  std::function<SessionParameters()> m_parameters;
  SessionAutosaver* m_saver;
  SessionLock m_lock;
  QString m_path;
  std::optional<ReadOnly> m_readOnly;
  std::vector<std::string> m_inputs;
  bool m_demo = false;
  bool m_demoAutosave = false;  ///< the file is the demo's autosave in the application's folder
  nlohmann::json m_settings = nlohmann::json::object();
  struct Next {
    std::vector<std::string> inputs;
    bool demo = false;
    QString path;
  };
  std::optional<Next> m_next;
  const FrameCube* m_sessionRaw = nullptr;                ///< the frames the current session belongs to
  const search::SearchResult* m_sessionResult = nullptr;  ///< the result of the last save
  bool m_hadVetting = false;  ///< a candidate of that result had a label, note or fit
  bool m_suspended = false;
  bool m_failing = false;
};

}  // namespace st::ui

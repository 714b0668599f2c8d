#include "session_controller.hpp"

#include <QCryptographicHash>
#include <QDir>
#include <QFile>
#include <QFileInfo>
#include <QRegularExpression>
#include <algorithm>
#include <QStandardPaths>
#include <cstring>

namespace st::ui {
namespace {

constexpr const char* kSuffix = ".synthtrack-session.json";

/// The input's name without FITS extensions (obs.fits.fz -> obs), or the folder's name.
QString baseName(const QFileInfo& info) {
  QString name = info.fileName();
  if (info.isDir()) return name;
  for (const char* ext : {".gz", ".fz", ".fits", ".fit", ".fts", ".FITS", ".FIT", ".FTS"})
    if (name.endsWith(QLatin1String(ext)) && name.size() > static_cast<int>(std::strlen(ext)))
      name.chop(static_cast<int>(std::strlen(ext)));
  return name;
}

}  // namespace

QString sessionFolder(const QString& folder) {
  return folder.isEmpty() ? QStandardPaths::writableLocation(QStandardPaths::AppDataLocation) + "/sessions"
                          : folder;
}

QString defaultSessionPath(const std::vector<std::string>& inputs, bool demo, const QString& folder) {
  const QString sessions = sessionFolder(folder);
  QDir().mkpath(sessions);
  if (demo || inputs.empty()) return QDir(sessions).filePath(QString("demo") + kSuffix);
  // NAME-HASH: the name for a person, the hash of the inputs' absolute paths so that two observations of
  // the same name (night1/obs.fits, night2/obs.fits) never share a file.
  QCryptographicHash hash(QCryptographicHash::Sha1);
  for (const auto& in : inputs)
    hash.addData(QFileInfo(QString::fromStdString(in)).absoluteFilePath().toUtf8().append('\n'));
  const QString tag = QString::fromLatin1(hash.result().toHex().left(8));
  return QDir(sessions).filePath(baseName(QFileInfo(QString::fromStdString(inputs.front()))) + "-" + tag +
                                 kSuffix);
}

QString legacySessionPath(const std::vector<std::string>& inputs) {
  if (inputs.empty()) return {};
  const QFileInfo first(QString::fromStdString(inputs.front()));
  return QDir(first.absolutePath()).filePath(baseName(first) + kSuffix);
}

QString freeSessionPath(const QString& path) {
  const auto taken = [](const QString& p) {
    return QFileInfo::exists(p) || QFileInfo::exists(SessionLock::lockPath(p));
  };
  if (!taken(path)) return path;
  QString stem = path;
  QString ext = ".json";
  if (stem.endsWith(ext)) stem.chop(ext.size());
  for (int i = 2;; ++i) {
    const QString candidate = QString("%1-%2%3").arg(stem).arg(i).arg(ext);
    if (!taken(candidate)) return candidate;
  }
}

QStringList pruneDemoAutosaves(const QString& folder, const QString& current, int keep) {
  static const QRegularExpression name(QString("^demo\\.synthtrack-session(-\\d+)?\\.json$"));
  const QFileInfo currentInfo(current);
  std::vector<QFileInfo> autosaves;
  for (const QFileInfo& info : QDir(folder).entryInfoList(QDir::Files, QDir::Time)) {  // newest first
    if (!name.match(info.fileName()).hasMatch() || info == currentInfo) continue;
    QFile file(info.absoluteFilePath());
    if (!file.open(QIODevice::ReadOnly)) continue;
    const nlohmann::json j = nlohmann::json::parse(file.readAll().toStdString(), nullptr, false);
    const nlohmann::json* mark = nullptr;
    if (j.is_object() && j.contains("parameters") && j["parameters"].is_object() &&
        j["parameters"].contains("observation") && j["parameters"]["observation"].is_object() &&
        j["parameters"]["observation"].contains("demo_autosave"))
      mark = &j["parameters"]["observation"]["demo_autosave"];
    if (mark && mark->is_boolean() && mark->get<bool>()) autosaves.push_back(info);
  }
  QStringList removed;
  for (std::size_t i = static_cast<std::size_t>(std::max(0, keep - 1)); i < autosaves.size(); ++i) {
    const QString path = autosaves[i].absoluteFilePath();
    SessionLock lock;
    if (!lock.acquire(path)) continue;  // open in a window or another process
    if (QFile::remove(path)) removed << path;
  }
  return removed;
}

SessionController::SessionController(Observation* observation, std::function<SessionParameters()> parameters,
                                     QObject* parent)
    : QObject(parent), m_obs(observation), m_parameters(std::move(parameters)) {
  m_saver = new SessionAutosaver(this);
  connect(m_saver, &SessionAutosaver::saved, this, &SessionController::onSaved);
  connect(m_saver, &SessionAutosaver::failed, this, &SessionController::onFailed);
  connect(m_obs, &Observation::rawChanged, this, &SessionController::requestSave);
  for (auto signal : {&Observation::preparedChanged, &Observation::resultChanged,
                      &Observation::selectionChanged, &Observation::unitChanged})
    connect(m_obs, signal, this, &SessionController::requestSave);
  connect(m_obs, &Observation::candidateStateChanged, this, &SessionController::requestSave);
  connect(m_obs, &Observation::candidateStateChanged, this, [this] {
    if (!m_readOnly || m_suspended) return;
    ++m_readOnly->unsavedChanges;  // a label, note or fit that this read-only window cannot save
    emit readOnlyChanged();
  });
}

SessionController::~SessionController() {
  m_saver->flush(10000);
}

void SessionController::setSettings(nlohmann::json settings) {
  m_settings = settings.is_object() ? std::move(settings) : nlohmann::json::object();
  requestSave();
}

void SessionController::prepareNew(std::vector<std::string> inputs, bool demo, const QString& path) {
  m_next = Next{std::move(inputs), demo, path};
}

void SessionController::adopt(const QString& path, std::vector<std::string> inputs, bool demo,
                              std::int64_t changes, nlohmann::json settings, bool demoAutosave) {
  m_next.reset();
  m_demoAutosave = demoAutosave;
  m_sessionRaw = m_obs->raw().get();  // the restored frames arrive next (suspended), then are this session's
  m_sessionResult = nullptr;
  m_hadVetting = false;
  m_inputs = std::move(inputs);
  m_demo = demo;
  m_settings = settings.is_object() ? std::move(settings) : nlohmann::json::object();
  if (setPath(path, changes))
    emit statusChanged("Session: " + path, "Every change is saved to this file", false);
}

void SessionController::saveAs(const QString& path) {
  if (!setPath(path, 0)) return;
  m_demoAutosave = false;  // saved by a person: never pruned
  requestSave();
}

bool SessionController::setPath(const QString& path, std::int64_t changes) {
  m_failing = false;
  if (!m_lock.acquire(path)) {
    // Open in another window or process: read-only here, said by the window's banner and the status bar.
    m_path.clear();
    const auto holder = SessionLock::holder(path);
    m_readOnly = ReadOnly{path, holder ? holder->describe() : QString("an unknown process"), 0};
    const QString text =
        "Session " + path + " is open in another synthtrack window or process (" + m_readOnly->holder +
        "): it is shown here read-only, and changes made here are NOT saved to it (File > Save session as… "
        "saves them elsewhere)";
    emit statusChanged("Session read-only: " + path + " is open elsewhere", text, true);
    emit readOnlyChanged();
    emit saveFailed(text);
    return false;
  }
  if (m_readOnly) {
    m_readOnly.reset();
    emit readOnlyChanged();
  }
  if (const auto& stale = m_lock.staleHolder(); stale && !(stale->pid == SessionLock::self().pid &&
                                                           stale->host == SessionLock::self().host))
    emit notice("A stale lock on " + path + " (left by " + stale->describe() +
                ", which ended without releasing it) was taken over");
  m_path = path;
  m_saver->setChangeCount(path, changes);
  emit pathChanged(path);
  return true;
}

void SessionController::startNext() {
  const Next next = std::move(*m_next);
  m_next.reset();
  m_inputs = next.inputs;
  m_demo = next.demo;
  const QString preferred = next.path.isEmpty() ? defaultSessionPath(m_inputs, m_demo) : next.path;
  const QString path = lockFreshPath(preferred);
  // A session of these inputs from before sessions moved out of the data folder is still offered.
  const QString legacy = next.path.isEmpty() && !m_demo ? legacySessionPath(m_inputs) : QString();
  if (path != preferred)
    emit notice("An earlier session of this observation is kept in " + preferred +
                " (File > Open session… resumes it); this one is saved to " + path);
  else if (!legacy.isEmpty() && QFileInfo::exists(legacy))
    emit notice("An earlier session of this observation is kept beside its frames in " + legacy +
                " (File > Open session… resumes it); this one is saved to " + path);
  m_settings = nlohmann::json::object();
  m_sessionResult = nullptr;
  m_hadVetting = false;
  m_demoAutosave = m_demo && next.path.isEmpty();
  if (!setPath(path, 0) || !m_demoAutosave) return;
  // Each demo run starts a new file: the older demo autosaves beyond the newest few go.
  const QStringList removed = pruneDemoAutosaves(QFileInfo(path).absolutePath(), path);
  if (!removed.isEmpty())
    emit notice(QString("Removed %1 older demo autosave%2 (the newest %3 are kept in %4)")
                    .arg(removed.size())
                    .arg(removed.size() == 1 ? "" : "s")
                    .arg(kDemoAutosavesKept)
                    .arg(QFileInfo(path).absolutePath()));
}

QString SessionController::lockFreshPath(const QString& preferred) {
  QString path = freeSessionPath(preferred);
  // A failed lock leaves its holder's lock file, so the next freeSessionPath() passes that name.
  for (int tries = 0; tries < 64 && !m_lock.acquire(path); ++tries)
    path = freeSessionPath(preferred);
  return path;  // setPath() keeps this lock (or says read-only, should all 64 names be taken meanwhile)
}

void SessionController::forkFile() {
  const QString kept = m_path;
  QString base = kept;
  // obs.synthtrack-session-3.json -> obs.synthtrack-session.json, then the first free name from there.
  static const QRegularExpression numbered("-\\d+\\.json$");
  base.replace(numbered, ".json");
  if (!setPath(lockFreshPath(base), 0)) return;
  emit notice("The vetted candidates were replaced by a new result; their session is kept in " + kept +
              ", this analysis goes on in " + m_path);
}

session::Session SessionController::currentSession() const {
  SessionParameters p = m_parameters ? m_parameters() : SessionParameters{};
  p.demo = m_demo;
  p.demoAutosave = m_demoAutosave;
  return makeSession(*m_obs, m_inputs, p, m_settings);
}

void SessionController::requestSave() {
  // A new observation: its session starts here, whichever of the Observation's listeners saves first (a
  // panel reacting to rawChanged before us must not write the new observation over the old file).
  if (m_obs->raw().get() != m_sessionRaw) {
    m_sessionRaw = m_obs->raw().get();
    if (m_next) {
      startNext();
    } else if (!m_suspended && !m_path.isEmpty()) {
      // Frames that came without prepareNew() or a session being opened: never saved over this file.
      emit notice("Autosave stopped: the observation changed outside a session (" + m_path + " is kept)");
      m_path.clear();
      m_lock.release();
      emit statusChanged("Session: none", "Open a session or the observation again to save", false);
    }
  }
  if (m_path.isEmpty()) return;
  // A new pre-processing run or search replaces the candidates: when some were vetted, that session is kept
  // as it is and the analysis goes on in a new file.
  const search::SearchResult* result = m_obs->result().get();
  if (result != m_sessionResult) {
    if (m_hadVetting && !m_suspended) forkFile();
    m_sessionResult = result;
  }
  m_hadVetting =
      std::any_of(m_obs->candidateStates().begin(), m_obs->candidateStates().end(), [](const auto& s) {
        return s.label != session::Label::Unvetted || !s.note.empty() || s.fit.has_value();
      });
  if (m_suspended) return;
  m_saver->request(m_path, currentSession());
}

void SessionController::onSaved(const QString& path, qint64 changes, double ms) {
  if (path != m_path) return;
  m_failing = false;
  emit statusChanged("Session: " + path,
                     QString("Saved (change %1, written in %2 ms); every change is saved to this file")
                         .arg(changes)
                         .arg(ms, 0, 'f', 1),
                     false);
}

void SessionController::onFailed(const QString& path, const QString& message) {
  const QString text = "Session NOT saved to " + path + ": " + message;
  emit statusChanged(text,
                     text +
                         "\nThe session stays in memory; the next change tries again, or use File > "
                         "Save session as… to choose another place.",
                     true);
  if (!m_failing) emit saveFailed(text);
  m_failing = true;
}

}  // namespace st::ui

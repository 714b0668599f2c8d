#include "session_controller.hpp"

#include <QDir>
#include <QFileInfo>
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

QString defaultSessionPath(const std::vector<std::string>& inputs, bool demo, const QString& fallbackDir) {
  QString fallback = fallbackDir;
  if (fallback.isEmpty())
    fallback = QStandardPaths::writableLocation(QStandardPaths::AppDataLocation) + "/sessions";
  if (demo || inputs.empty()) {
    QDir().mkpath(fallback);
    return QDir(fallback).filePath(QString("demo") + kSuffix);
  }
  const QFileInfo first(QString::fromStdString(inputs.front()));
  const QString name = baseName(first) + kSuffix;
  const QFileInfo dir(first.absolutePath());
  if (dir.isDir() && dir.isWritable()) return QDir(first.absolutePath()).filePath(name);
  QDir().mkpath(fallback);
  return QDir(fallback).filePath(name);
}

QString freeSessionPath(const QString& path) {
  if (!QFileInfo::exists(path)) return path;
  QString stem = path;
  QString ext = ".json";
  if (stem.endsWith(ext)) stem.chop(ext.size());
  for (int i = 2;; ++i) {
    const QString candidate = QString("%1-%2%3").arg(stem).arg(i).arg(ext);
    if (!QFileInfo::exists(candidate)) return candidate;
  }
}

SessionController::SessionController(Observation* observation, std::function<SessionParameters()> parameters,
                                     QObject* parent)
    : QObject(parent), m_obs(observation), m_parameters(std::move(parameters)) {
  m_saver = new SessionAutosaver(this);
  connect(m_saver, &SessionAutosaver::saved, this, &SessionController::onSaved);
  connect(m_saver, &SessionAutosaver::failed, this, &SessionController::onFailed);
  connect(m_obs, &Observation::rawChanged, this, &SessionController::onRawChanged);
  for (auto signal : {&Observation::preparedChanged, &Observation::resultChanged,
                      &Observation::selectionChanged, &Observation::unitChanged})
    connect(m_obs, signal, this, &SessionController::requestSave);
  connect(m_obs, &Observation::candidateStateChanged, this, &SessionController::requestSave);
}

void SessionController::setSettings(nlohmann::json settings) {
  m_settings = settings.is_object() ? std::move(settings) : nlohmann::json::object();
  requestSave();
}

void SessionController::prepareNew(std::vector<std::string> inputs, bool demo, const QString& path) {
  m_next = Next{std::move(inputs), demo, path};
}

void SessionController::adopt(const QString& path, std::vector<std::string> inputs, bool demo,
                              std::int64_t changes, nlohmann::json settings) {
  m_next.reset();
  m_path = path;
  m_inputs = std::move(inputs);
  m_demo = demo;
  m_settings = settings.is_object() ? std::move(settings) : nlohmann::json::object();
  m_failing = false;
  m_saver->setChangeCount(path, changes);
  emit pathChanged(path);
  emit statusChanged("Session: " + path, "Every change is saved to this file", false);
}

void SessionController::saveAs(const QString& path) {
  m_path = path;
  m_saver->setChangeCount(path, 0);
  m_failing = false;
  emit pathChanged(path);
  requestSave();
}

void SessionController::onRawChanged() {
  if (!m_next) {
    requestSave();
    return;
  }
  const Next next = std::move(*m_next);
  m_next.reset();
  m_inputs = next.inputs;
  m_demo = next.demo;
  m_path = next.path.isEmpty() ? freeSessionPath(defaultSessionPath(m_inputs, m_demo)) : next.path;
  m_settings = nlohmann::json::object();
  m_failing = false;
  m_saver->setChangeCount(m_path, 0);
  emit pathChanged(m_path);
  requestSave();
}

session::Session SessionController::currentSession() const {
  SessionParameters p = m_parameters ? m_parameters() : SessionParameters{};
  p.demo = m_demo;
  return makeSession(*m_obs, m_inputs, p, m_settings);
}

void SessionController::requestSave() {
  if (m_path.isEmpty() || m_suspended) return;
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

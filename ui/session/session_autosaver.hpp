#pragma once
// Writes session files off the GUI thread (issue 8 §6). One serial worker thread: requests are queued and
// written one after the other through st::session::SessionStore (temporary file, fsync, rename, fsync of the
// folder), so a crash leaves either the previous or the new complete file. A request for a path that is
// still waiting in the queue replaces it (the newest state wins: bursts of changes cost one write, never a
// backlog). The GUI thread only builds the Session object and hands it over; it never waits on the disk
// (flush() excepted, for closing the window and tests).
//
// What a crash can lose: the changes not yet written when it happens. At a person's pace (a change every
// few hundred ms, a save in a few ms) that is at most the last change; tests/ui/test_session_autosave.cpp
// kills a labelling process with SIGKILL to check it.
#include <QObject>
#include <QString>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <map>
#include <mutex>
#include <thread>

#include "st/session/session.hpp"

namespace st::ui {

class SessionAutosaver : public QObject {
  Q_OBJECT
 public:
  explicit SessionAutosaver(QObject* parent = nullptr);
  /// Writes what is still queued (at most 10 s), then stops the worker.
  ~SessionAutosaver() override;

  /// Queues `session` for `path` and returns at once. Session::changes is set by the worker: the number of
  /// saves of that path so far (counting on from setChangeCount()) plus one.
  void request(const QString& path, session::Session session);
  /// The count of saves already in the file at `path` (a session that was opened), 0 by default.
  void setChangeCount(const QString& path, std::int64_t changes);
  /// Waits until every queued save was written or failed, at most `timeoutMs`; true when nothing is left.
  bool flush(int timeoutMs = 10000);
  /// Requests waiting or being written.
  [[nodiscard]] int pending() const;

 signals:
  /// Emitted from the worker thread (queued to receivers on other threads).
  void saved(const QString& path, qint64 changes, double milliseconds);
  /// The save failed; `message` names the path (SessionStore's message) and the session stays in memory:
  /// the next change tries again.
  void failed(const QString& path, const QString& message);

 private:
  struct Request {
    QString path;
    session::Session session;
  };
  void run();

  mutable std::mutex m_mutex;
  std::condition_variable m_wake;
  std::condition_variable m_idle;
  std::deque<Request> m_queue;
  std::map<QString, std::int64_t> m_changes;
  bool m_writing = false;
  bool m_stop = false;
  std::thread m_thread;
};

}  // namespace st::ui

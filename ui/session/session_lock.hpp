#pragma once
// One writer per session file: an advisory lock (flock) on NAME.lock beside it, held while a window
// autosaves to the file. A second window or synthtrack process that opens the same session gets no lock and
// does not write (last-writer-wins would silently drop the other window's labels). The lock goes with the
// process (flock is released by the kernel on exit, also after kill -9); the .lock file is removed on
// release.
#include <QString>

namespace st::ui {

class SessionLock {
 public:
  SessionLock() = default;
  ~SessionLock() { release(); }
  SessionLock(const SessionLock&) = delete;
  SessionLock& operator=(const SessionLock&) = delete;

  /// Locks `sessionPath` (releasing any lock held before). False when another holder has it. When the lock
  /// file cannot be created (a read-only folder), true without a lock: saving there fails on its own, with a
  /// message naming the path.
  bool acquire(const QString& sessionPath);
  /// Releases the lock and removes the lock file (nothing when none is held).
  void release();
  /// The lock file of a session file.
  [[nodiscard]] static QString lockPath(const QString& sessionPath) { return sessionPath + ".lock"; }

 private:
  int m_fd = -1;
  QString m_path;
};

}  // namespace st::ui

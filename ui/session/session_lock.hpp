#pragma once
// One writer per session file: an advisory lock (flock) on NAME.lock beside it, held while a window
// autosaves to the file. A second window or synthtrack process that opens the same session gets no lock and
// opens it read-only (SessionController::readOnly(): last-writer-wins would silently drop the other window's
// labels). The lock file says who holds it ("pid PID host HOST"), for the read-only banner. The lock goes
// with the process (flock is released by the kernel on exit, also after kill -9): a lock file left behind by
// a crash is stale, and the next window takes it over and says so (staleHolder()). The .lock file is removed
// on release.
#include <QString>
#include <optional>

namespace st::ui {

class SessionLock {
 public:
  /// Who holds (or held) a lock, from its lock file.
  struct Holder {
    qint64 pid = 0;
    QString host;
    /// "synthtrack pid 1234 on host node7" (or "another synthtrack window" when the file says nothing).
    [[nodiscard]] QString describe() const;
  };

  SessionLock() = default;
  ~SessionLock() { release(); }
  SessionLock(const SessionLock&) = delete;
  SessionLock& operator=(const SessionLock&) = delete;

  /// Locks `sessionPath` (releasing any lock held before) and writes this process's pid and host into the
  /// lock file. False when another holder has it. When the lock file cannot be created (a read-only
  /// folder), true without a lock: saving there fails on its own, with a message naming the path.
  bool acquire(const QString& sessionPath);
  /// Releases the lock and removes the lock file (nothing when none is held).
  void release();
  /// The lock file of a session file.
  [[nodiscard]] static QString lockPath(const QString& sessionPath) { return sessionPath + ".lock"; }
  /// Who the lock file of `sessionPath` names (empty when there is none or it names no one). It is the
  /// live holder when acquire() fails.
  [[nodiscard]] static std::optional<Holder> holder(const QString& sessionPath);
  /// After a successful acquire(): the holder a stale lock file named (a process that ended without
  /// releasing it: crashed or killed), whose lock was taken over; empty otherwise.
  [[nodiscard]] const std::optional<Holder>& staleHolder() const noexcept { return m_stale; }
  /// This process's pid and host, as written into lock files.
  [[nodiscard]] static Holder self();

 private:
  int m_fd = -1;
  QString m_path;
  std::optional<Holder> m_stale;
};

}  // namespace st::ui

#include "session_lock.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <QFile>
#include <QSysInfo>
#include <QRegularExpression>

namespace st::ui {
namespace {

/// "pid 1234 host node7": what a lock file says.
std::optional<SessionLock::Holder> parseHolder(const QByteArray& text) {
  static const QRegularExpression line(QStringLiteral("pid (\\d+) host (\\S+)"));
  const auto match = line.match(QString::fromUtf8(text));
  if (!match.hasMatch()) return std::nullopt;
  return SessionLock::Holder{match.captured(1).toLongLong(), match.captured(2)};
}

std::optional<SessionLock::Holder> readHolder(int fd) {
  QByteArray text(256, '\0');
  const ssize_t n = ::pread(fd, text.data(), static_cast<size_t>(text.size()), 0);
  if (n <= 0) return std::nullopt;
  text.truncate(static_cast<int>(n));
  return parseHolder(text);
}

}  // namespace

QString SessionLock::Holder::describe() const {
  if (pid <= 0) return QStringLiteral("another synthtrack window");
  return QString("synthtrack pid %1 on host %2").arg(pid).arg(host);
}

SessionLock::Holder SessionLock::self() {
  return {static_cast<qint64>(::getpid()), QSysInfo::machineHostName()};
}

std::optional<SessionLock::Holder> SessionLock::holder(const QString& sessionPath) {
  QFile file(lockPath(sessionPath));
  if (!file.open(QIODevice::ReadOnly)) return std::nullopt;
  return parseHolder(file.read(256));
}

bool SessionLock::acquire(const QString& sessionPath) {
  if (m_fd >= 0 && m_path == sessionPath) return true;
  release();
  m_stale.reset();
  const QByteArray file = lockPath(sessionPath).toLocal8Bit();
  const int fd = ::open(file.constData(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) return true;  // no lock possible here; the save reports the folder's problem
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    ::close(fd);
    return false;
  }
  // Locked: a holder still named in the file ended without releasing it (the kernel dropped its flock).
  m_stale = readHolder(fd);
  const Holder me = self();
  const QByteArray text = QString("pid %1 host %2\n").arg(me.pid).arg(me.host).toUtf8();
  if (::ftruncate(fd, 0) == 0) (void)!::pwrite(fd, text.constData(), static_cast<size_t>(text.size()), 0);
  m_fd = fd;
  m_path = sessionPath;
  return true;
}

void SessionLock::release() {
  if (m_fd < 0) return;
  ::unlink(lockPath(m_path).toLocal8Bit().constData());
  ::close(m_fd);
  m_fd = -1;
  m_path.clear();
}

}  // namespace st::ui

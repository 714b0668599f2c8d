#include "session_lock.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

namespace st::ui {

bool SessionLock::acquire(const QString& sessionPath) {
  if (m_fd >= 0 && m_path == sessionPath) return true;
  release();
  const QByteArray file = lockPath(sessionPath).toLocal8Bit();
  const int fd = ::open(file.constData(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) return true;  // no lock possible here; the save reports the folder's problem
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    ::close(fd);
    return false;
  }
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

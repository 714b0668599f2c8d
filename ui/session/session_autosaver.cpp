#include "session_autosaver.hpp"

#include <chrono>
#include <exception>

namespace st::ui {

SessionAutosaver::SessionAutosaver(QObject* parent) : QObject(parent) {
  m_thread = std::thread([this] { run(); });
}

SessionAutosaver::~SessionAutosaver() {
  flush(10000);
  {
    std::lock_guard lock(m_mutex);
    m_stop = true;
  }
  m_wake.notify_all();
  m_thread.join();
}

void SessionAutosaver::request(const QString& path, session::Session session) {
  {
    std::lock_guard lock(m_mutex);
    // Coalesce with a waiting request for the same file (one being written is no longer in the queue).
    bool replaced = false;
    for (auto& r : m_queue)
      if (r.path == path) {
        r.session = std::move(session);
        replaced = true;
        break;
      }
    if (!replaced) m_queue.push_back({path, std::move(session)});
  }
  m_wake.notify_one();
}

void SessionAutosaver::setChangeCount(const QString& path, std::int64_t changes) {
  std::lock_guard lock(m_mutex);
  m_changes[path] = changes;
}

bool SessionAutosaver::flush(int timeoutMs) {
  std::unique_lock lock(m_mutex);
  return m_idle.wait_for(lock, std::chrono::milliseconds(timeoutMs),
                         [this] { return m_queue.empty() && !m_writing; });
}

int SessionAutosaver::pending() const {
  std::lock_guard lock(m_mutex);
  return static_cast<int>(m_queue.size()) + (m_writing ? 1 : 0);
}

void SessionAutosaver::run() {
  std::unique_lock lock(m_mutex);
  while (true) {
    m_wake.wait(lock, [this] { return m_stop || !m_queue.empty(); });
    if (m_queue.empty()) return;  // stopping, nothing left
    Request r = std::move(m_queue.front());
    m_queue.pop_front();
    m_writing = true;
    r.session.changes = m_changes[r.path];
    lock.unlock();
    const auto start = std::chrono::steady_clock::now();
    QString error;
    try {
      session::SessionStore(r.path.toStdString()).save(r.session);  // increments changes
    } catch (const std::exception& e) {
      error = QString::fromStdString(e.what());
    }
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    lock.lock();
    if (error.isEmpty()) m_changes[r.path] = r.session.changes;
    m_writing = false;
    lock.unlock();
    // Signals outside the lock: a direct-connected receiver may call request() or pending().
    if (error.isEmpty())
      emit saved(r.path, static_cast<qint64>(r.session.changes), ms);
    else
      emit failed(r.path, error);
    lock.lock();
    if (m_queue.empty() && !m_writing) m_idle.notify_all();
  }
}

}  // namespace st::ui

#include "stack_scrubber.hpp"

#include <chrono>
#include <exception>

namespace st::ui {
namespace {
std::int64_t nowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}
}  // namespace

StackScrubber::StackScrubber(QObject* parent) : QObject(parent) {
  qRegisterMetaType<std::shared_ptr<const st::Image>>();
  qRegisterMetaType<st::ui::StackRequest>();
  m_thread = std::thread([this] { loop(); });
}

StackScrubber::~StackScrubber() {
  {
    std::lock_guard lock(m_mutex);
    m_stop = true;
  }
  m_wake.notify_all();
  m_thread.join();
}

void StackScrubber::setBackend(std::shared_ptr<search::SearchBackend> backend) {
  std::lock_guard lock(m_mutex);
  m_backend = std::move(backend);
}

std::int64_t StackScrubber::request(std::shared_ptr<const search::FilteredCube> cube, Velocity v,
                                    search::StackMode mode, int tag) {
  std::int64_t serial = 0;
  {
    std::lock_guard lock(m_mutex);
    serial = ++m_serial;
    if (m_pending.count(tag) != 0) ++m_dropped;
    // Latency counts from the newest input: what the user waits for.
    m_pending[tag] = {StackRequest{std::move(cube), v, mode, tag, serial}, nowNs()};
  }
  m_wake.notify_one();
  return serial;
}

void StackScrubber::loop() {
  for (;;) {
    StackRequest req;
    std::int64_t startNs = 0;
    std::shared_ptr<search::SearchBackend> backend;
    {
      std::unique_lock lock(m_mutex);
      m_wake.wait(lock, [this] { return m_stop || !m_pending.empty(); });
      if (m_stop) return;
      auto it = m_pending.begin();
      req = std::move(it->second.first);
      startNs = it->second.second;
      m_pending.erase(it);
      backend = m_backend;
    }
    try {
      if (!backend || !req.cube) throw std::runtime_error("no stack backend");
      const std::int64_t t0 = nowNs();
      auto image = std::make_shared<const Image>(backend->stackAt(*req.cube, req.velocity, req.mode));
      const std::int64_t t1 = nowNs();
      ++m_computed;
      const double computeMs = (t1 - t0) / 1e6;
      const double latencyMs = (t1 - startNs) / 1e6;
      QMetaObject::invokeMethod(
          this,
          [this, image, req, latencyMs, computeMs] { emit stackReady(image, req, latencyMs, computeMs); },
          Qt::QueuedConnection);
    } catch (const std::exception& e) {
      const QString message = QString::fromStdString(e.what());
      QMetaObject::invokeMethod(
          this, [this, message] { emit stackFailed(message); }, Qt::QueuedConnection);
    }
  }
}

}  // namespace st::ui

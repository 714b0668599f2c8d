#include "job_runner.hpp"

#include <exception>

#ifdef __linux__
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>
#endif

#include "core_services.hpp"
#include "st/common/error.hpp"

namespace st::ui {

void throwMissingService(const char* name) {
  throw InputError(std::string("this build of synthtrack has no ") + name);
}

void PolledProgress::report(double fraction, std::string_view stage) {
  std::lock_guard lock(m_mutex);
  m_fraction = fraction;
  m_stage.assign(stage);
}

std::pair<double, std::string> PolledProgress::latest() const {
  std::lock_guard lock(m_mutex);
  return {m_fraction, m_stage};
}

void PolledProgress::reset() {
  std::lock_guard lock(m_mutex);
  m_fraction = 0.0;
  m_stage.clear();
}

QString jobName(JobKind kind) {
  switch (kind) {
    case JobKind::Load:
      return "Loading";
    case JobKind::Preprocess:
      return "Pre-processing";
    case JobKind::Search:
      return "Searching";
    case JobKind::OpenSession:
      return "Opening session";
    case JobKind::Fit:
      return "Fitting";
    case JobKind::PlateSolve:
      return "Plate solving";
  }
  return "Working";
}

JobRunner::JobRunner(QObject* parent) : QObject(parent) {
  m_worker = new QObject;
  m_worker->moveToThread(&m_thread);
  connect(&m_thread, &QThread::finished, m_worker, &QObject::deleteLater);
  m_thread.setObjectName("st-job");
  m_thread.start();
#ifdef __linux__
  // Batch work runs at a lower CPU priority than the GUI thread (nice +5, per thread on Linux; threads the
  // core starts from here inherit it), so a busy machine still repaints and answers the mouse.
  QMetaObject::invokeMethod(
      m_worker, [] { setpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)), 5); },
      Qt::QueuedConnection);
#endif
  m_poll.setInterval(50);
  connect(&m_poll, &QTimer::timeout, this, [this] {
    const auto [fraction, stage] = m_progress.latest();
    emit progress(fraction, QString::fromStdString(stage), m_clock.elapsed() / 1000.0);
  });
}

JobRunner::~JobRunner() {
  if (m_cancel) m_cancel->cancel();
  m_thread.quit();
  m_thread.wait();
}

bool JobRunner::start(JobKind kind, Work work) {
  if (m_busy) return false;
  m_busy = true;
  m_kind = kind;
  m_cancel = std::make_shared<CancelToken>();
  m_progress.reset();
  m_clock.start();
  m_poll.start();
  emit started(kind);
  auto cancel = m_cancel;
  QMetaObject::invokeMethod(
      m_worker,
      [this, work = std::move(work), cancel] {
        std::function<void()> apply;
        bool cancelled = false;
        QString error;
        try {
          apply = work(m_progress, *cancel);
        } catch (const Cancelled&) {
          cancelled = true;
        } catch (const std::exception& e) {
          error = QString::fromStdString(e.what());
          if (error.isEmpty()) error = "unknown error";
        } catch (...) {
          error = "unknown error";
        }
        QMetaObject::invokeMethod(
            this, [this, apply = std::move(apply), cancelled, error] { onWorkDone(apply, cancelled, error); },
            Qt::QueuedConnection);
      },
      Qt::QueuedConnection);
  return true;
}

void JobRunner::cancel() {
  if (m_cancel) m_cancel->cancel();
}

void JobRunner::onWorkDone(std::function<void()> apply, bool cancelled, const QString& error) {
  m_poll.stop();
  const double elapsed = m_clock.elapsed() / 1000.0;
  QString message = error;
  bool ok = !cancelled && error.isEmpty();
  if (ok && apply) {
    try {
      apply();
    } catch (const std::exception& e) {
      ok = false;
      message = QString::fromStdString(e.what());
    }
  }
  m_busy = false;
  emit finished(m_kind, ok, cancelled, message, elapsed);
}

}  // namespace st::ui

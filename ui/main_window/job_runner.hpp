#pragma once
// Threading rules of the GUI (ARCHITECTURE.md, "Threads, errors, memory"):
//  - The GUI thread never computes and never waits. Long work (load, pre-process, search) runs as a Job on
//    the runner's worker QThread, one job at a time.
//  - A job gets a ProgressSink and a CancelToken. Progress is stored (thread-safe) and the GUI polls it at
//    20 Hz, so a chatty core cannot flood the event loop.
//  - A job returns an "apply" closure; it runs on the GUI thread when the job is done, and is the only
//    place results touch widgets or GUI state. Exceptions never leave the worker: they become failed().
#include <QElapsedTimer>
#include <QObject>
#include <QString>
#include <QThread>
#include <QTimer>
#include <atomic>
#include <functional>
#include <memory>
#include <mutex>
#include <string>

#include "st/common/progress.hpp"

namespace st::ui {

/// Thread-safe store of the latest progress report.
class PolledProgress final : public ProgressSink {
 public:
  void report(double fraction, std::string_view stage) override;
  /// The latest fraction and stage.
  std::pair<double, std::string> latest() const;
  void reset();

 private:
  mutable std::mutex m_mutex;
  double m_fraction = 0.0;
  std::string m_stage;
};

/// What a job is. The GUI tells jobs apart by this, never by the text it shows (jobName).
enum class JobKind { Load, Preprocess, Search, OpenSession, Fit, PlateSolve };

/// The text shown for a job in the status bar and in messages: "Loading", "Pre-processing", "Searching",
/// "Opening session", "Fitting", "Plate solving".
QString jobName(JobKind kind);

class JobRunner : public QObject {
  Q_OBJECT
 public:
  /// The work; returns what to do on the GUI thread with the result (may be empty).
  using Work = std::function<std::function<void()>(ProgressSink&, CancelToken&)>;

  explicit JobRunner(QObject* parent = nullptr);
  ~JobRunner() override;

  /// Starts `work` as a job of `kind`. Returns false (and does nothing) while another job runs.
  bool start(JobKind kind, Work work);
  /// Asks the running job to stop; it answers at its next CancelToken poll.
  void cancel();
  [[nodiscard]] bool busy() const noexcept { return m_busy; }
  /// The running (or last) job's kind, and its name as shown (jobName).
  [[nodiscard]] JobKind currentKind() const noexcept { return m_kind; }
  [[nodiscard]] QString currentName() const { return jobName(m_kind); }

 signals:
  void started(st::ui::JobKind kind);
  /// Polled progress: fraction in [0, 1], the core's stage text, seconds since start.
  void progress(double fraction, const QString& stage, double elapsedS);
  /// The job ended: ok, cancelled, or failed with the core's message. Emitted after the apply closure ran.
  void finished(st::ui::JobKind kind, bool ok, bool cancelled, const QString& message, double elapsedS);

 private:
  void onWorkDone(std::function<void()> apply, bool cancelled, const QString& error);

  QThread m_thread;
  QObject* m_worker = nullptr;  // lives in m_thread
  QTimer m_poll;
  QElapsedTimer m_clock;
  PolledProgress m_progress;
  std::shared_ptr<CancelToken> m_cancel;
  JobKind m_kind = JobKind::Load;
  bool m_busy = false;
};

}  // namespace st::ui

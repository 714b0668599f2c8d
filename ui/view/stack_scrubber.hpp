#pragma once
// Live stacks for scrubbing velocity space. Requests come from the GUI thread as fast as the user moves;
// one worker thread computes the stack with its own search backend ("latest request wins": requests that
// arrive while a stack is being computed replace each other, only the newest is computed next), then posts
// the image back with the time from request to result. The GUI thread never waits.
#include <QObject>
#include <atomic>
#include <condition_variable>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>

#include "st/common/image.hpp"
#include "st/search/types.hpp"

namespace st::ui {

struct StackRequest {
  std::shared_ptr<const search::FilteredCube> cube;
  Velocity velocity;
  search::StackMode mode = search::StackMode::Ipsa;
  int tag = 0;  ///< caller's label (e.g. which view asked), returned with the result
  std::int64_t serial = 0;
};

class StackScrubber : public QObject {
  Q_OBJECT
 public:
  explicit StackScrubber(QObject* parent = nullptr);
  ~StackScrubber() override;

  /// The backend used for stacks (not shared with a running search). Takes effect at the next request.
  void setBackend(std::shared_ptr<search::SearchBackend> backend);
  /// Queues a stack; replaces any request with the same tag still waiting. Returns its serial number.
  std::int64_t request(std::shared_ptr<const search::FilteredCube> cube, Velocity v, search::StackMode mode,
                       int tag = 0);
  /// Requests computed so far and requests dropped because a newer one came first.
  [[nodiscard]] std::int64_t computedCount() const noexcept { return m_computed; }
  [[nodiscard]] std::int64_t droppedCount() const noexcept { return m_dropped; }

 signals:
  /// A stack is ready. `latencyMs`: request to result; `computeMs`: the stack alone.
  void stackReady(std::shared_ptr<const st::Image> image, const st::ui::StackRequest& request,
                  double latencyMs, double computeMs);
  void stackFailed(const QString& message);

 private:
  void loop();

  std::mutex m_mutex;
  std::condition_variable m_wake;
  std::map<int, std::pair<StackRequest, std::int64_t>> m_pending;  // per tag: newest request, its time (ns)
  std::shared_ptr<search::SearchBackend> m_backend;
  bool m_stop = false;
  std::int64_t m_serial = 0;
  std::atomic<std::int64_t> m_computed{0};
  std::atomic<std::int64_t> m_dropped{0};
  std::thread m_thread;
};

}  // namespace st::ui

#pragma once
// The work queue of a batch (issue 17): observations handed out one at a time in a fixed order (largest
// first), what each worker holds, and what is lost when a worker dies. Bookkeeping only: the transport
// (MPI or a loop in one process) is the caller's.
#include <cstddef>
#include <deque>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace st::batch {

class BatchQueue {
 public:
  /// `order`: the indices to hand out, first first.
  explicit BatchQueue(const std::vector<std::size_t>& order);
  /// The next index for `worker` (recorded as held by it), or nullopt when none is left.
  std::optional<std::size_t> next(int worker);
  /// `worker` finished what it held (done or failed).
  void finished(int worker);
  /// `worker` is gone: what it held (nullopt when nothing) is returned and no longer in flight.
  std::optional<std::size_t> lose(int worker);
  [[nodiscard]] std::optional<std::size_t> heldBy(int worker) const;
  [[nodiscard]] std::size_t pending() const noexcept { return m_pending.size(); }
  [[nodiscard]] std::size_t inFlight() const noexcept { return m_held.size(); }
  /// Indices never handed out, in order (to name what was not done when the batch stops early).
  [[nodiscard]] std::vector<std::size_t> pendingIndices() const {
    return {m_pending.begin(), m_pending.end()};
  }

 private:
  std::deque<std::size_t> m_pending;
  std::map<int, std::size_t> m_held;
};

/// "12/480 observations (3 skipped, 1 failed), 95.3/h, ETA 4h52m": `done` counts finished ones of `total`,
/// the rate is over those processed in this run (`processed` in `elapsedS` seconds), the ETA the remaining
/// ones at that rate ("ETA -" before the first). Pure.
std::string progressLine(std::size_t done, std::size_t total, std::size_t skipped, std::size_t failed,
                         std::size_t processed, double elapsedS);

}  // namespace st::batch

#pragma once
// Narrow, toolkit-free interfaces through which long core work reports progress and is cancelled
// (STYLE.md: Stellarium's progress state, Siril's atomic "should continue" flag). The GUI adapts
// ProgressSink to queued Qt signals; the CLI draws a terminal bar.
#include <atomic>
#include <string_view>

#include "st/common/error.hpp"

namespace st {

/// Receives progress of long work. `fraction` is in [0, 1]; `stage` names what is being done.
/// Implementations must be thread-safe: parallel loops may report from worker threads.
struct ProgressSink {
  virtual ~ProgressSink() = default;
  virtual void report(double fraction, std::string_view stage) = 0;
};

/// A sink that drops everything (tests, nested calls that report elsewhere).
struct NullProgress final : ProgressSink {
  void report(double, std::string_view) override {}
};

/// Maps [0, 1] of a sub-task onto [lo, hi] of a parent sink, for stages chained by the pipeline.
class SubProgress final : public ProgressSink {
 public:
  SubProgress(ProgressSink& parent, double lo, double hi) : m_parent(parent), m_lo(lo), m_hi(hi) {}
  void report(double fraction, std::string_view stage) override {
    m_parent.report(m_lo + (m_hi - m_lo) * fraction, stage);
  }

 private:
  ProgressSink& m_parent;
  double m_lo;
  double m_hi;
};

/// Cooperative cancellation: one thread calls cancel(), long loops call throwIfCancelled() often enough
/// to answer within a fraction of a second.
class CancelToken {
 public:
  void cancel() noexcept { m_cancelled.store(true, std::memory_order_relaxed); }
  void reset() noexcept { m_cancelled.store(false, std::memory_order_relaxed); }
  [[nodiscard]] bool cancelled() const noexcept { return m_cancelled.load(std::memory_order_relaxed); }
  void throwIfCancelled() const {
    if (cancelled()) throw Cancelled();
  }

 private:
  std::atomic<bool> m_cancelled{false};
};

}  // namespace st

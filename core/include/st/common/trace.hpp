#pragma once
// A timeline of the pipeline's parts, for finding where the wall time of a run goes (issue 16: which stage
// waits for which copy or device call). Off unless the environment names a file: ST_TRACE=run.json writes
// every traced part of the process, on every thread, as Chrome trace events ("ph": "X"), readable by
// Perfetto (ui.perfetto.dev), chrome://tracing and scripts/trace_summary.py, when the process exits.
// Recording costs a steady_clock read and, while on, a locked push per part; off, one relaxed load. The
// events stay in memory until the process exits (a long GUI session holds them all; a crash writes none), and
// a child process inherits ST_TRACE and writes the same file: trace one process at a time.
#include <chrono>
#include <string>
#include <string_view>

namespace st::trace {

using Clock = std::chrono::steady_clock;

/// True while parts are being recorded (ST_TRACE set at the first call, or start() called).
[[nodiscard]] bool enabled() noexcept;
/// Records one part that ran on this thread from `begin` to `end` (nothing when not enabled).
void record(std::string_view name, Clock::time_point begin, Clock::time_point end);
/// Starts recording for `path` (replacing ST_TRACE's file); the events recorded so far are kept.
void start(const std::string& path);
/// Writes the events recorded so far to the file (the whole file again: it stays valid JSON) and returns
/// how many there are; 0 and nothing written when not enabled. Throws st::Error when it cannot write.
std::size_t flush();
/// Stops recording and forgets the events (flush() first to keep them).
void stop();

/// Records the part from its construction to its destruction, on the thread that made it.
class Scope {
 public:
  explicit Scope(std::string_view name) : m_on(enabled()) {
    if (m_on) {
      m_name = name;
      m_begin = Clock::now();
    }
  }
  ~Scope() {
    if (m_on) record(m_name, m_begin, Clock::now());
  }
  Scope(const Scope&) = delete;
  Scope& operator=(const Scope&) = delete;

 private:
  bool m_on;
  std::string m_name;
  Clock::time_point m_begin;
};

}  // namespace st::trace

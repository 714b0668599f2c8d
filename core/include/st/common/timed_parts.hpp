#pragma once
// Wall time of a stage's parts, for the pipeline's notes: one record and one formatter for every stage that
// times its parts (the cosmic rays, the sky rate, the static-source searches).
#include <chrono>
#include <string>
#include <vector>

namespace st {

struct TimedPart {
  std::string name;
  double seconds = 0.0;
  /// The process's CPU seconds meanwhile (every thread's, so also work beside the part's), when timed by a
  /// PartTimer; 0 for a part added as it is (e.g. a thread-time sum).
  double cpuSeconds = 0.0;
};

/// The parts in the order they were first timed.
struct TimedParts {
  std::vector<TimedPart> parts;

  /// Adds `seconds` (and `cpuSeconds`) to the part `name` (a new part at the end when there is none).
  void add(const std::string& name, double seconds, double cpuSeconds = 0.0);
  /// Adds each of `other`'s parts as above, its name prefixed with `prefix` (a sub-stage's parts under the
  /// stage's).
  void add(const TimedParts& other, const std::string& prefix = {});
  /// The part's seconds; 0 when it was not timed.
  [[nodiscard]] double seconds(const std::string& name) const;
  /// "name 1.2 ms, name 3.4 ms (2.5 cores), ..." (empty when nothing was timed): the cores, CPU time over
  /// wall time, where the CPU time was measured.
  [[nodiscard]] std::string text() const;
};

/// Times consecutive parts: each lap(name) adds the wall time since the previous lap (or since the timer
/// was made) to that part.
class PartTimer {
 public:
  explicit PartTimer(TimedParts& out);
  /// Adds the time since the last lap to `name`; returns it, seconds.
  double lap(const std::string& name);

 private:
  TimedParts& m_out;
  std::chrono::steady_clock::time_point m_last;
  double m_lastCpu = 0.0;
};

}  // namespace st

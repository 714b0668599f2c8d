#pragma once
// --timings of the command-line jobs: when each step ended, seconds from the job's start, on stderr
// ("timings: STEP  S s"), and the pre-processing stages' own seconds indented under them. Silent when off.
#include <chrono>
#include <string>
#include <utility>
#include <vector>

namespace st::app {

class StepTimings {
 public:
  explicit StepTimings(bool on) : m_on(on), m_start(std::chrono::steady_clock::now()) {}
  [[nodiscard]] bool on() const { return m_on; }
  /// Seconds since the start.
  [[nodiscard]] double elapsed() const;
  /// "timings: WHAT  S s", S the seconds since the start.
  void mark(const char* what) const;
  /// Each stage with its own seconds, indented (a Prepared's stageSeconds).
  void stages(const std::vector<std::pair<std::string, double>>& stageSeconds) const;
  /// "timings: WHAT  S s", S the seconds given.
  void line(const char* what, double seconds) const;

 private:
  bool m_on;
  std::chrono::steady_clock::time_point m_start;
};

}  // namespace st::app

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
};

/// The parts in the order they were first timed.
struct TimedParts {
  std::vector<TimedPart> parts;

  /// Adds `seconds` to the part `name` (a new part at the end when there is none).
  void add(const std::string& name, double seconds);
  /// The part's seconds; 0 when it was not timed.
  [[nodiscard]] double seconds(const std::string& name) const;
  /// "name 1.2 ms, name 3.4 ms, ..." (empty when nothing was timed).
  [[nodiscard]] std::string text() const;
};

/// Times consecutive parts: each lap(name) adds the wall time since the previous lap (or since the timer
/// was made) to that part.
class PartTimer {
 public:
  explicit PartTimer(TimedParts& out) : m_out(out), m_last(std::chrono::steady_clock::now()) {}
  /// Adds the time since the last lap to `name`; returns it, seconds.
  double lap(const std::string& name);

 private:
  TimedParts& m_out;
  std::chrono::steady_clock::time_point m_last;
};

}  // namespace st

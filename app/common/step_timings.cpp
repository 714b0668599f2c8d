#include "step_timings.hpp"

#include <cstdio>

namespace st::app {

double StepTimings::elapsed() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - m_start).count();
}

void StepTimings::mark(const char* what) const {
  line(what, elapsed());
}

void StepTimings::line(const char* what, double seconds) const {
  if (m_on) std::fprintf(stderr, "timings: %-34s %8.3f s\n", what, seconds);
}

void StepTimings::stages(const std::vector<std::pair<std::string, double>>& stageSeconds) const {
  if (!m_on) return;
  for (const auto& [stage, seconds] : stageSeconds)
    std::fprintf(stderr, "timings:   %-32s %8.3f s\n", stage.c_str(), seconds);
}

}  // namespace st::app

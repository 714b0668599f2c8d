#pragma once
// A ProgressSink that draws a one-line bar on stderr when stderr is a terminal, and otherwise (a log file, a
// pipe, a batch job) writes a plain line at most every 30 s (ST_PROGRESS_LINE_S) once a job has run that
// long; and the SIGINT handling that turns Ctrl-C into a cancel of the running job.
#include <atomic>
#include <chrono>
#include <mutex>
#include <string>

#include "st/common/progress.hpp"

namespace st::app {

class TerminalProgress final : public ProgressSink {
 public:
  TerminalProgress();
  ~TerminalProgress() override;
  void report(double fraction, std::string_view stage) override;
  /// Clears the bar line (call before printing results).
  void finish();

 private:
  std::mutex m_mutex;
  bool m_enabled;
  bool m_drawn = false;
  int m_lastPermille = -1;
  std::string m_lastStage;
  std::chrono::steady_clock::time_point m_start;
  double m_lineIntervalS;           ///< seconds between plain lines (not a terminal)
  std::atomic<double> m_nextLineS;  ///< seconds from the start before which no plain line is written
};

/// The token cancelled by Ctrl-C (SIGINT) once installSigintCancel() has run. A second Ctrl-C exits at once.
CancelToken& processCancelToken();
void installSigintCancel();

}  // namespace st::app

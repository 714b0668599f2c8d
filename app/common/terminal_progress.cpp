#include "terminal_progress.hpp"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <cstdlib>

namespace st::app {

namespace {
// Seconds between the plain lines written when stderr is not a terminal: ST_PROGRESS_LINE_S when a
// positive number (the tests' short jobs), else 30.
double lineIntervalS() {
  if (const char* env = std::getenv("ST_PROGRESS_LINE_S")) {
    char* end = nullptr;
    const double v = std::strtod(env, &end);
    if (end != env && v > 0.0) return v;
  }
  return 30.0;
}
}  // namespace

TerminalProgress::TerminalProgress()
    : m_enabled(isatty(STDERR_FILENO) != 0),
      m_start(std::chrono::steady_clock::now()),
      m_lineIntervalS(lineIntervalS()),
      m_nextLineS(m_lineIntervalS) {}

TerminalProgress::~TerminalProgress() {
  finish();
}

void TerminalProgress::report(double fraction, std::string_view stage) {
  if (!m_enabled) {
    // A log's reader sees that a long job is alive and how far it is, without a line per step. The threads
    // that report meanwhile only read the clock and an atomic.
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - m_start).count();
    if (elapsed < m_nextLineS.load(std::memory_order_relaxed)) return;
    std::lock_guard lock(m_mutex);
    if (elapsed < m_nextLineS.load(std::memory_order_relaxed)) return;
    m_nextLineS.store(elapsed + m_lineIntervalS, std::memory_order_relaxed);
    const double f = std::clamp(fraction, 0.0, 1.0);
    if (f >= 0.02 && f < 1.0)
      std::fprintf(stderr, "progress: %.1f%% after %.0f s (about %.0f s left): %.*s\n", 100.0 * f, elapsed,
                   elapsed * (1.0 - f) / f, static_cast<int>(stage.size()), stage.data());
    else
      std::fprintf(stderr, "progress: %.1f%% after %.0f s: %.*s\n", 100.0 * f, elapsed,
                   static_cast<int>(stage.size()), stage.data());
    std::fflush(stderr);
    return;
  }
  std::lock_guard lock(m_mutex);
  const int permille = static_cast<int>(fraction * 1000.0);
  if (permille == m_lastPermille && stage == m_lastStage) return;
  m_lastPermille = permille;
  m_lastStage = std::string(stage);
  constexpr int kWidth = 30;
  const int filled = std::clamp(permille * kWidth / 1000, 0, kWidth);
  const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - m_start).count();
  std::fprintf(stderr, "\r[%.*s%*s] %5.1f%% %6.1fs %-32.32s", filled, "##############################",
               kWidth - filled, "", permille / 10.0, elapsed, m_lastStage.c_str());
  std::fflush(stderr);
  m_drawn = true;
}

void TerminalProgress::finish() {
  std::lock_guard lock(m_mutex);
  if (m_enabled && m_drawn) {
    std::fprintf(stderr, "\r%*s\r", 90, "");
    std::fflush(stderr);
    m_drawn = false;
  }
}

CancelToken& processCancelToken() {
  static CancelToken token;
  return token;
}

namespace {
std::atomic<int> g_interrupts{0};  // lock-free, so safe to touch from a signal handler
void onSigint(int) {
  if (++g_interrupts >= 2) std::_Exit(130);
  processCancelToken().cancel();  // an atomic store: async-signal-safe for lock-free atomics
}
}  // namespace

void installSigintCancel() {
  std::signal(SIGINT, onSigint);
}

}  // namespace st::app

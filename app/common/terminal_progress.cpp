#include "terminal_progress.hpp"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <cstdlib>

namespace st::app {

TerminalProgress::TerminalProgress()
    : m_enabled(isatty(STDERR_FILENO) != 0), m_start(std::chrono::steady_clock::now()) {}

TerminalProgress::~TerminalProgress() {
  finish();
}

void TerminalProgress::report(double fraction, std::string_view stage) {
  if (!m_enabled) return;
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

#pragma once
// Wall-clock phases of one search on the host (set-up, upload, chunks, read-back, candidates), for the
// backend's note: where the end-to-end time goes besides the kernels.
#include <chrono>
#include <cstdio>
#include <string>

namespace st::gpu {

class WallPhases {
 public:
  /// Ends the current phase, named `name`, and starts the next.
  void mark(const char* name) {
    const auto now = std::chrono::steady_clock::now();
    char buf[64];
    std::snprintf(buf, sizeof(buf), "%s%s %.1f ms", m_text.empty() ? "" : ", ", name,
                  1e3 * std::chrono::duration<double>(now - m_last).count());
    m_text += buf;
    m_last = now;
  }
  [[nodiscard]] const std::string& str() const { return m_text; }

 private:
  std::chrono::steady_clock::time_point m_last = std::chrono::steady_clock::now();
  std::string m_text;
};

}  // namespace st::gpu

#include "st/common/timed_parts.hpp"

#include <algorithm>
#include <cstdio>

namespace st {

void TimedParts::add(const std::string& name, double seconds) {
  const auto it = std::find_if(parts.begin(), parts.end(), [&](const TimedPart& p) { return p.name == name; });
  if (it != parts.end())
    it->seconds += seconds;
  else
    parts.push_back({name, seconds});
}

double TimedParts::seconds(const std::string& name) const {
  const auto it = std::find_if(parts.begin(), parts.end(), [&](const TimedPart& p) { return p.name == name; });
  return it != parts.end() ? it->seconds : 0.0;
}

std::string TimedParts::text() const {
  std::string out;
  for (const TimedPart& p : parts) {
    char ms[32];
    std::snprintf(ms, sizeof ms, " %.1f ms", 1e3 * p.seconds);
    out += (out.empty() ? "" : ", ") + p.name + ms;
  }
  return out;
}

double PartTimer::lap(const std::string& name) {
  const auto now = std::chrono::steady_clock::now();
  const double s = std::chrono::duration<double>(now - m_last).count();
  m_last = now;
  m_out.add(name, s);
  return s;
}

}  // namespace st

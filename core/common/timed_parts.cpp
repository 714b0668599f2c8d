#include "st/common/timed_parts.hpp"

#include <algorithm>
#include <cstdio>

#include "st/common/cpu_time.hpp"
#include "st/common/trace.hpp"

namespace st {

void TimedParts::add(const std::string& name, double seconds, double cpuSeconds) {
  const auto it =
      std::find_if(parts.begin(), parts.end(), [&](const TimedPart& p) { return p.name == name; });
  if (it != parts.end()) {
    it->seconds += seconds;
    it->cpuSeconds += cpuSeconds;
  } else {
    parts.push_back({name, seconds, cpuSeconds});
  }
}

void TimedParts::add(const TimedParts& other, const std::string& prefix) {
  for (const TimedPart& p : other.parts)
    add(prefix + p.name, p.seconds, p.cpuSeconds);
}

double TimedParts::seconds(const std::string& name) const {
  const auto it =
      std::find_if(parts.begin(), parts.end(), [&](const TimedPart& p) { return p.name == name; });
  return it != parts.end() ? it->seconds : 0.0;
}

std::string TimedParts::text() const {
  std::string out;
  for (const TimedPart& p : parts) {
    char ms[48];
    if (p.cpuSeconds > 0.0 && p.seconds > 0.0)
      std::snprintf(ms, sizeof ms, " %.1f ms (%.1f cores)", 1e3 * p.seconds, p.cpuSeconds / p.seconds);
    else
      std::snprintf(ms, sizeof ms, " %.1f ms", 1e3 * p.seconds);
    out += (out.empty() ? "" : ", ") + p.name + ms;
  }
  return out;
}

PartTimer::PartTimer(TimedParts& out)
    : m_out(out), m_last(std::chrono::steady_clock::now()), m_lastCpu(processCpuSeconds()) {}

double PartTimer::lap(const std::string& name) {
  const auto now = std::chrono::steady_clock::now();
  const double cpu = processCpuSeconds();
  const double s = std::chrono::duration<double>(now - m_last).count();
  m_out.add(name, s, cpu - m_lastCpu);
  trace::record(name, m_last, now);
  m_last = now;
  m_lastCpu = cpu;
  return s;
}

}  // namespace st

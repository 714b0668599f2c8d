#include "st/common/trace.hpp"

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <vector>

#include "st/common/error.hpp"

namespace st::trace {
namespace {

struct Event {
  std::string name;
  unsigned thread;
  Clock::time_point begin, end;
};

struct State {
  std::mutex mutex;
  std::atomic<bool> on{false};
  std::string path;
  std::vector<Event> events;
  Clock::time_point origin = Clock::now();
  std::atomic<unsigned> threads{0};

  State() {
    if (const char* p = std::getenv("ST_TRACE"); p && *p) {
      path = p;
      on.store(true);
    }
  }

  std::size_t flushLocked();
};

// Never destroyed: threads that outlive main's return (the parallelFor pool's) may still record.
State& state();

// The process's events written as it exits (a failure to write is reported on stderr: exit cannot throw).
void flushAtExit() {
  try {
    flush();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "trace: %s\n", e.what());
  }
}

State& state() {
  static State* s = [] {
    auto* made = new State;
    std::atexit(flushAtExit);
    return made;
  }();
  return *s;
}

unsigned threadNumber() {
  thread_local const unsigned n = state().threads.fetch_add(1);
  return n;
}

void appendEscaped(std::string& out, std::string_view s) {
  for (const char c : s) {
    if (c == '"' || c == '\\')
      out += '\\', out += c;
    else if (static_cast<unsigned char>(c) < 0x20)
      out += ' ';
    else
      out += c;
  }
}

std::size_t State::flushLocked() {
  if (!on.load() || path.empty()) return 0;
  // Times from the earliest part's start (a part may have begun before the trace's state was made).
  Clock::time_point first = origin;
  for (const Event& e : events)
    first = std::min(first, e.begin);
  std::string text = "{\"traceEvents\":[\n";
  char num[96];
  for (std::size_t i = 0; i < events.size(); ++i) {
    const Event& e = events[i];
    const double ts = std::chrono::duration<double, std::micro>(e.begin - first).count();
    const double dur = std::chrono::duration<double, std::micro>(e.end - e.begin).count();
    text += "{\"name\":\"";
    appendEscaped(text, e.name);
    std::snprintf(num, sizeof num, "\",\"ph\":\"X\",\"pid\":1,\"tid\":%u,\"ts\":%.1f,\"dur\":%.1f}", e.thread,
                  ts, dur);
    text += num;
    text += i + 1 < events.size() ? ",\n" : "\n";
  }
  text += "],\"displayTimeUnit\":\"ms\"}\n";
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) throw Error("trace: cannot write " + path);
  const bool ok = std::fwrite(text.data(), 1, text.size(), f) == text.size();
  if (std::fclose(f) != 0 || !ok) throw Error("trace: writing " + path + " failed");
  return events.size();
}

}  // namespace

bool enabled() noexcept {
  return state().on.load(std::memory_order_relaxed);
}

void record(std::string_view name, Clock::time_point begin, Clock::time_point end) {
  State& s = state();
  if (!s.on.load(std::memory_order_relaxed)) return;
  const unsigned thread = threadNumber();
  const std::lock_guard lock(s.mutex);
  s.events.push_back({std::string(name), thread, begin, end});
}

void start(const std::string& path) {
  State& s = state();
  const std::lock_guard lock(s.mutex);
  s.path = path;
  s.on.store(true);
}

std::size_t flush() {
  State& s = state();
  const std::lock_guard lock(s.mutex);
  return s.flushLocked();
}

void stop() {
  State& s = state();
  const std::lock_guard lock(s.mutex);
  s.on.store(false);
  s.events.clear();
  s.path.clear();
}

}  // namespace st::trace

#include "st/common/memory_budget.hpp"

#include <unistd.h>
#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include "st/common/error.hpp"
#include "st/common/prefault.hpp"

namespace st {
namespace {

std::optional<std::size_t> readNumberFile(const std::string& path) {
  std::ifstream in(path);
  std::string text;
  if (!(in >> text) || text == "max") return std::nullopt;
  try {
    const unsigned long long v = std::stoull(text);
    // cgroup v1 reports "no limit" as a huge number (page-rounded LONG_MAX)
    if (v >= (1ULL << 60)) return std::nullopt;
    return static_cast<std::size_t>(v);
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

std::optional<std::size_t> meminfoKb(const std::string& key) {
  std::ifstream in("/proc/meminfo");
  std::string name;
  unsigned long long kb = 0;
  std::string unit;
  while (in >> name >> kb) {
    std::getline(in, unit);
    if (name == key + ":") return static_cast<std::size_t>(kb) * 1024;
  }
  return std::nullopt;
}

}  // namespace

std::size_t parseMemorySize(const std::string& text, const std::string& what) {
  std::string t;
  for (const char c : text)
    if (!std::isspace(static_cast<unsigned char>(c))) t.push_back(c);
  const auto bad = [&] {
    return InputError(what + ": '" + text +
                      "' is not a memory size (a positive number with an optional K, M, G or T, e.g. 8G or "
                      "500M)");
  };
  std::size_t pos = 0;
  double v = 0.0;
  try {
    v = std::stod(t, &pos);
  } catch (const std::exception&) {
    throw bad();
  }
  std::string unit = t.substr(pos);
  for (auto& c : unit)
    c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  if (unit.size() >= 2 && unit.substr(unit.size() - 2) == "IB") unit.resize(unit.size() - 2);
  if (!unit.empty() && unit.back() == 'B' && unit.size() <= 2) unit.pop_back();
  double scale = 1.0;
  if (unit == "K") scale = 1024.0;
  else if (unit == "M") scale = 1024.0 * 1024.0;
  else if (unit == "G") scale = 1024.0 * 1024.0 * 1024.0;
  else if (unit == "T") scale = 1024.0 * 1024.0 * 1024.0 * 1024.0;
  else if (!unit.empty()) throw bad();
  const double bytes = v * scale;
  if (!(bytes >= 1.0) || !std::isfinite(bytes) || bytes > 1e18) throw bad();
  return static_cast<std::size_t>(bytes);
}

std::string formatBytes(double bytes) {
  char buf[64];
  const double k = 1024.0;
  if (bytes >= k * k * k) {
    std::snprintf(buf, sizeof buf, "%.2f GB", bytes / (k * k * k));
  } else if (bytes >= k * k) {
    std::snprintf(buf, sizeof buf, "%.0f MB", bytes / (k * k));
  } else {
    std::snprintf(buf, sizeof buf, "%.0f kB", bytes / k);
  }
  return buf;
}

std::size_t SystemMemory::usableBytes() const {
  std::size_t u = availableBytes;
  if (cgroupLimit) {
    const std::size_t used = cgroupUsage.value_or(0);
    u = std::min(u, *cgroupLimit > used ? *cgroupLimit - used : std::size_t{0});
  }
  return u;
}

SystemMemory readSystemMemory() {
  SystemMemory m;
  if (const auto a = meminfoKb("MemAvailable")) {
    m.availableBytes = *a;
  } else {
    const long pages = sysconf(_SC_AVPHYS_PAGES);
    const long size = sysconf(_SC_PAGE_SIZE);
    m.availableBytes = pages > 0 && size > 0 ? static_cast<std::size_t>(pages) * size : std::size_t{1} << 30;
  }
  if (const auto v2 = readNumberFile("/sys/fs/cgroup/memory.max")) {
    m.cgroupLimit = v2;
    m.cgroupUsage = readNumberFile("/sys/fs/cgroup/memory.current");
  } else if (const auto v1 = readNumberFile("/sys/fs/cgroup/memory/memory.limit_in_bytes")) {
    m.cgroupLimit = v1;
    m.cgroupUsage = readNumberFile("/sys/fs/cgroup/memory/memory.usage_in_bytes");
  }
  return m;
}

std::size_t defaultMemoryBudget() {
  const double b = kDefaultBudgetFraction * static_cast<double>(readSystemMemory().usableBytes());
  return std::max<std::size_t>(static_cast<std::size_t>(b), std::size_t{64} << 20);
}

MemoryBudget resolveMemoryBudget(const std::optional<std::string>& given) {
  if (given) return {parseMemorySize(*given), "--memory-limit " + *given};
  const SystemMemory m = readSystemMemory();
  std::ostringstream os;
  os << "default: " << static_cast<int>(kDefaultBudgetFraction * 100) << "% of " << formatBytes(m.usableBytes())
     << " available";
  if (m.cgroupLimit) os << " (cgroup limit " << formatBytes(static_cast<double>(*m.cgroupLimit)) << ")";
  return {defaultMemoryBudget(), os.str()};
}

double MemoryEstimate::total() const {
  double t = 0.0;
  for (const auto& p : parts)
    t += p.bytes;
  return t;
}

std::string MemoryEstimate::describe() const {
  std::ostringstream os;
  os << formatBytes(total()) << " (";
  bool first = true;
  for (const auto& p : parts) {
    if (p.bytes <= 0.0) continue;
    os << (first ? "" : ", ") << p.what << " " << formatBytes(p.bytes);
    first = false;
  }
  os << ")";
  return os.str();
}

void releaseFreeHeapMemory() {
#if defined(__GLIBC__)
  malloc_trim(0);
#endif
}

namespace {
// Scopes alive now (pre-processing's and the tiled search's may nest): only the outermost sets the
// thresholds and sets them back.
std::atomic<int> g_heapReuseDepth{0};
}  // namespace

HeapReuseScope::HeapReuseScope() {
#if defined(__GLIBC__)
  if (g_heapReuseDepth.fetch_add(1) > 0) return;
  mallopt(M_MMAP_THRESHOLD, 1 << 30);
  mallopt(M_TRIM_THRESHOLD, 1 << 30);
#endif
}

void HeapReuseScope::warmCallerHeap(std::size_t bytes) {
#if defined(__GLIBC__)
  if (g_heapReuseDepth.load() == 0 || bytes < (std::size_t{1} << 20)) return;
  void* block = std::malloc(bytes);
  if (!block) return;
  touchPages(block, bytes);
  std::free(block);
#else
  (void)bytes;
#endif
}

HeapReuseScope::~HeapReuseScope() {
#if defined(__GLIBC__)
  if (g_heapReuseDepth.fetch_sub(1) > 1) return;
  mallopt(M_MMAP_THRESHOLD, 128 * 1024);
  mallopt(M_TRIM_THRESHOLD, 128 * 1024);
  malloc_trim(0);
#endif
}

std::size_t peakResidentBytes() {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("VmHWM:", 0) == 0) {
      std::istringstream is(line.substr(6));
      unsigned long long kb = 0;
      is >> kb;
      return static_cast<std::size_t>(kb) * 1024;
    }
  }
  return 0;
}

}  // namespace st

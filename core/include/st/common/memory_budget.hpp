#pragma once
// The memory budget of one run (issue 20): how many bytes a run may hold, what the system allows, a typed
// estimate of a run's peak with its parts, and the process's own peak resident memory (for tests and bench).
//
// Default budget: kDefaultBudgetFraction of the memory available now (MemAvailable in /proc/meminfo), capped
// by the same fraction of what the cgroup still allows (cgroup v2 memory.max - memory.current, or v1
// memory.limit_in_bytes - memory.usage_in_bytes), so that the run is never the one the OOM killer picks.
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

namespace st {

/// Fraction of the available memory a run takes by default.
inline constexpr double kDefaultBudgetFraction = 0.7;

/// Parses a size such as "8G", "500M", "1.5GiB", "2048K" or "123456" (bytes). K/M/G/T are powers of 1024
/// (with or without a trailing "B" or "iB"). Throws st::InputError naming `what` and the text when it is not
/// a positive size.
std::size_t parseMemorySize(const std::string& text, const std::string& what = "--memory-limit");

/// "1.23 GB" / "456 MB" / "12 kB" (powers of 1024, one unit per size).
std::string formatBytes(double bytes);

/// What the system says now.
struct SystemMemory {
  std::size_t availableBytes = 0;           ///< MemAvailable (or physical memory when unreadable)
  std::optional<std::size_t> cgroupLimit;   ///< memory.max / memory.limit_in_bytes when limited
  std::optional<std::size_t> cgroupUsage;   ///< memory.current / memory.usage_in_bytes
  [[nodiscard]] std::size_t usableBytes() const;  ///< min(available, cgroup limit - usage)
};

SystemMemory readSystemMemory();

/// kDefaultBudgetFraction x readSystemMemory().usableBytes(), at least 64 MB.
std::size_t defaultMemoryBudget();

/// The budget of a run: `given` (parsed with parseMemorySize) or the default; `source` says which.
struct MemoryBudget {
  std::size_t bytes = 0;
  std::string source;  ///< "--memory-limit 8G" or "default: 70% of 12.3 GB available"
};
MemoryBudget resolveMemoryBudget(const std::optional<std::string>& given);

/// A run's estimated peak: its parts (name, bytes) and their sum.
struct MemoryEstimate {
  struct Part {
    std::string what;
    double bytes = 0.0;
  };
  std::vector<Part> parts;
  void add(std::string what, double bytes) { parts.push_back({std::move(what), bytes}); }
  [[nodiscard]] double total() const;
  /// "1.2 GB (cube 512 MB, filtered cube 512 MB, ...)"
  [[nodiscard]] std::string describe() const;
};

/// Peak resident set of this process so far (VmHWM, bytes); 0 when unreadable.
std::size_t peakResidentBytes();

/// Gives the heap's free pages back to the system (glibc's malloc_trim(0), every arena; nothing elsewhere).
/// Between the stages of an out-of-core run: the allocator keeps what a stage freed in its threads' arenas
/// (measured: ~70 MB resident after pre-processing 100 x 256 x 1024 in strips with 2 threads), which the
/// next stage's estimate does not count.
void releaseFreeHeapMemory();

/// While alive, large blocks the heap frees are kept for the next allocation instead of being unmapped
/// (glibc: mmap and trim thresholds raised to 1 GiB; nothing elsewhere); at its end the glibc defaults
/// (128 KiB) are set back and the free pages released. For loops that allocate and free the same large
/// buffers over and over (the out-of-core search's tiles): the kernel no longer faults and zeroes their pages
/// each time (measured: 400 x 512^2 tree search in 14 tiles, 0.9 -> 0.2 s of system time, +6 MB VmHWM).
class HeapReuseScope {
 public:
  HeapReuseScope();
  ~HeapReuseScope();
  HeapReuseScope(const HeapReuseScope&) = delete;
  HeapReuseScope& operator=(const HeapReuseScope&) = delete;

  /// Faults `bytes` of the calling thread's heap on every core, then frees them: the heap keeps them (the
  /// raised trim threshold), and that thread's next allocations, up to that size in all, take pages already
  /// there instead of faulting and zeroing each new one on that thread. Nothing when no scope is alive, off
  /// glibc, or below 1 MiB. Pre-processing's serial stages fault ~60 ms of fresh canvas-sized images on the
  /// main thread without it (perf, H100, 2026-11-28).
  static void warmCallerHeap(std::size_t bytes);
};

}  // namespace st

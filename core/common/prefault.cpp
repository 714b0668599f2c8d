#include "st/common/prefault.hpp"

#include <cstring>

#include "st/common/parallel.hpp"

#ifdef __linux__
#include <sys/mman.h>
#include <unistd.h>
#endif

namespace st {
namespace {

// Populates the whole pages of [data, data + bytes) on parallelFor's threads, when large enough to pay.
void populate(void* data, std::size_t bytes, unsigned maxThreads) {
#ifdef __linux__
  constexpr std::uintptr_t kPage = 4096;
  const auto begin = reinterpret_cast<std::uintptr_t>(data);
  const std::uintptr_t lo = (begin + kPage - 1) & ~(kPage - 1);
  const std::uintptr_t hi = (begin + bytes) & ~(kPage - 1);
  if (hi > lo + (std::size_t{64} << 20)) {  // only worth it for large buffers
    // A hint (on the whole pages): ignored where transparent huge pages are off.
    madvise(reinterpret_cast<void*>(lo), hi - lo, MADV_HUGEPAGE);
    touchPages(data, bytes, maxThreads);
  }
#else
  (void)data, (void)bytes, (void)maxThreads;
#endif
}

// n elements of a default-initialising vector (PixelVector, MaskVector), unwritten, their pages populated.
template <class Vector>
Vector populated(std::size_t n, unsigned maxThreads) {
  Vector v;
  v.reserve(n);  // allocated, not touched
  populate(v.data(), n * sizeof(typename Vector::value_type), maxThreads);
  v.resize(n);  // no write (DefaultInitAllocator)
  return v;
}

// Zeros written on every core over vector v's populated pages.
template <class Vector>
void zeroInParallel(Vector& v) {
  using T = typename Vector::value_type;
  const std::size_t chunk = (std::size_t{16} << 20) / sizeof(T);  // 16 MiB
  parallelFor(v.size(), chunk,
              [&](std::size_t b, std::size_t e) { std::memset(v.data() + b, 0, (e - b) * sizeof(T)); });
}

}  // namespace

void touchPages(void* data, std::size_t bytes, unsigned maxThreads) {
  constexpr std::uintptr_t kPage = 4096;
  const auto begin = reinterpret_cast<std::uintptr_t>(data);
  const std::uintptr_t lo = (begin + kPage - 1) & ~(kPage - 1);
  const std::uintptr_t hi = (begin + bytes) & ~(kPage - 1);
  if (hi <= lo) return;
  // A page fault takes only its own VMA's lock (Linux >= 6.4; the mmap lock for one fault before), where a
  // populate call holds the mmap lock for its whole range: the matched filter's buffer, populated on one
  // thread while the stages run, stalled registration's threads ~180 ms on the device machine in 64 MiB
  // calls and still ~40 ms in 2 MiB ones (perf, H100, 2026-11-28). Dev VM, 1.5 GB on one thread: 0.18 s,
  // another thread's mmap + munmap waiting at most 0.5 ms (populate calls of 64 MiB: 0.16 s, waits up to
  // 113 ms). The zeros written change nothing the callers read: they zero or overwrite every element.
  auto* base = reinterpret_cast<char*>(lo);
  constexpr std::size_t kChunkPages = 4096;  // 16 MiB per task
  parallelFor((hi - lo) / kPage, kChunkPages,
              [base](std::size_t p0, std::size_t p1) {
                volatile char* page = base;
                for (std::size_t p = p0; p < p1; ++p)
                  page[p * kPage] = 0;
              },
              maxThreads);
}

PixelVector prefaultedPixels(std::size_t n, unsigned maxThreads) {
  return populated<PixelVector>(n, maxThreads);
}

PixelVector prefaultedZeros(std::size_t n, float) {
  PixelVector v = populated<PixelVector>(n, 0);
  zeroInParallel(v);
  return v;
}

MaskVector prefaultedZeros(std::size_t n, std::uint8_t) {
  MaskVector v = populated<MaskVector>(n, 0);
  zeroInParallel(v);
  return v;
}

void zeroSparse(std::uint8_t* data, std::size_t n) {
#ifdef __linux__
  const long pageSize = sysconf(_SC_PAGESIZE);  // 4 KiB on x86-64; 16 or 64 KiB on some arm64 kernels
  const std::uintptr_t page = pageSize > 0 ? static_cast<std::uintptr_t>(pageSize) : 4096;
  const auto begin = reinterpret_cast<std::uintptr_t>(data);
  const std::uintptr_t lo = (begin + page - 1) & ~(page - 1);
  const std::uintptr_t hi = (begin + n) & ~(page - 1);
  // Whole pages of [data, data + n) only: whatever shares a page with its ends (an allocator's headers, a
  // neighbour) is not touched. No huge pages there: a few bytes written in each 2 MiB would fault and clear
  // the whole of it (transparent huge pages "always").
  if (n >= std::size_t{1} << 20 && hi > lo) {
    madvise(reinterpret_cast<void*>(lo), hi - lo, MADV_NOHUGEPAGE);
    if (madvise(reinterpret_cast<void*>(lo), hi - lo, MADV_DONTNEED) == 0) {
      std::memset(data, 0, lo - begin);
      std::memset(reinterpret_cast<void*>(hi), 0, begin + n - hi);
      return;
    }
  }
#endif
  std::memset(data, 0, n);
}

MaskVector sparseZeros(std::size_t n) {
  if (n <= (std::size_t{64} << 20)) return prefaultedZeros(n, std::uint8_t{0});
  MaskVector v;
  v.reserve(n);  // from the heap or a fresh mapping: private anonymous memory either way
  v.resize(n);   // no write (DefaultInitAllocator)
  zeroSparse(v.data(), n);
  return v;
}

}  // namespace st

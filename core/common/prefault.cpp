#include "st/common/prefault.hpp"

#include "st/common/parallel.hpp"

#ifdef __linux__
#include <sys/mman.h>
#ifndef MADV_POPULATE_WRITE
#define MADV_POPULATE_WRITE 23  // Linux 5.14
#endif
#endif

namespace st {
namespace {

template <class T>
std::vector<T> prefaulted(std::size_t n) {
  std::vector<T> v;
  v.reserve(n);  // allocated, not touched: its pages are faulted in below, before the zero fill
#ifdef __linux__
  constexpr std::uintptr_t kPage = 4096;
  const auto begin = reinterpret_cast<std::uintptr_t>(v.data());
  const std::uintptr_t lo = (begin + kPage - 1) & ~(kPage - 1);
  const std::uintptr_t hi = (begin + n * sizeof(T)) & ~(kPage - 1);
  if (hi > lo + (std::size_t{64} << 20)) {  // only worth it for large buffers
    auto* base = reinterpret_cast<char*>(lo);
    const std::size_t pages = (hi - lo) / kPage;
    madvise(base, hi - lo, MADV_HUGEPAGE);      // a hint: ignored where transparent huge pages are off
    constexpr std::size_t kChunkPages = 16384;  // 64 MiB
    parallelFor(pages, kChunkPages, [&](std::size_t p0, std::size_t p1) {
      madvise(base + p0 * kPage, (p1 - p0) * kPage, MADV_POPULATE_WRITE);  // failure: faulted by resize
    });
  }
#endif
  v.resize(n);
  return v;
}

}  // namespace

std::vector<float> prefaultedZeros(std::size_t n, float) { return prefaulted<float>(n); }
std::vector<std::uint8_t> prefaultedZeros(std::size_t n, std::uint8_t) { return prefaulted<std::uint8_t>(n); }

}  // namespace st

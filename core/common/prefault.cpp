#include "st/common/prefault.hpp"

#include <cstring>

#include "st/common/parallel.hpp"

#ifdef __linux__
#include <sys/mman.h>
#ifndef MADV_POPULATE_WRITE
#define MADV_POPULATE_WRITE 23  // Linux 5.14
#endif
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
    auto* base = reinterpret_cast<char*>(lo);
    const std::size_t pages = (hi - lo) / kPage;
    madvise(base, hi - lo, MADV_HUGEPAGE);      // a hint: ignored where transparent huge pages are off
    constexpr std::size_t kChunkPages = 16384;  // 64 MiB
    parallelFor(
        pages, kChunkPages,
        [&](std::size_t p0, std::size_t p1) {
          madvise(base + p0 * kPage, (p1 - p0) * kPage,
                  MADV_POPULATE_WRITE);  // failure: faulted when written
        },
        maxThreads);
  }
#else
  (void)data, (void)bytes, (void)maxThreads;
#endif
}

}  // namespace

PixelVector prefaultedPixels(std::size_t n, unsigned maxThreads) {
  PixelVector v;
  v.reserve(n);  // allocated, not touched
  populate(v.data(), n * sizeof(float), maxThreads);
  v.resize(n);  // no write (DefaultInitAllocator)
  return v;
}

PixelVector prefaultedZeros(std::size_t n, float) {
  PixelVector v = prefaultedPixels(n);
  constexpr std::size_t kChunk = std::size_t{1} << 22;  // 16 MiB of floats
  parallelFor(n, kChunk,
              [&](std::size_t b, std::size_t e) { std::memset(v.data() + b, 0, (e - b) * sizeof(float)); });
  return v;
}

std::vector<std::uint8_t> prefaultedZeros(std::size_t n, std::uint8_t) {
  std::vector<std::uint8_t> v;
  v.reserve(n);
  populate(v.data(), n, 0);
  v.resize(n);
  return v;
}

}  // namespace st

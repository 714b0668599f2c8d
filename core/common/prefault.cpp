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
    // A failed populate is harmless: the pages are then faulted when first written.
    const auto body = [&](std::size_t p0, std::size_t p1) {
      madvise(base + p0 * kPage, (p1 - p0) * kPage, MADV_POPULATE_WRITE);
    };
    parallelFor(pages, kChunkPages, body, maxThreads);
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

}  // namespace st

#pragma once
// Large buffers (a whole cube, or its mask) allocated without paying their page faults on one core.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "st/common/pixel_vector.hpp"

namespace st {

/// Faults every whole page of [data, data + bytes) by writing a zero to its first byte, on parallelFor's
/// threads (`maxThreads` as below). Not madvise(MADV_POPULATE_WRITE): that holds the process's mmap lock for
/// its whole range, and every other thread's mmap, munmap, mprotect or brk waits (prefault.cpp).
void touchPages(void* data, std::size_t bytes, unsigned maxThreads = 0);

/// n floats whose values are unspecified (to be overwritten), their pages already in memory: on Linux the
/// pages of a large buffer (> 64 MiB) are faulted with touchPages (huge pages where allowed) instead of one
/// page fault per 4 KiB on one thread as they are first written; elsewhere just allocated. `maxThreads` caps
/// the threads (0: workerCount(); 1: this thread only, for an allocation made behind other work).
PixelVector prefaultedPixels(std::size_t n, unsigned maxThreads = 0);

/// n zeros, written on every core (after prefaultedPixels).
PixelVector prefaultedZeros(std::size_t n, float);

/// n zeros (a cube's mask), written on every core after the pages are populated as above.
MaskVector prefaultedZeros(std::size_t n, std::uint8_t);

}  // namespace st

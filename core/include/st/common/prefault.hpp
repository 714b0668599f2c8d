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

/// Zeros [data, data + n) for a buffer that will be written only here and there (a sparse mask): on Linux,
/// for n >= 1 MiB, its whole pages are given back to the kernel (madvise MADV_DONTNEED on private anonymous
/// memory: read as zeros, each given its own zeroed page only where it is first written) and the partial
/// pages at its ends are written with zeros; bytes outside the range are never touched. Elsewhere, memset.
void zeroSparse(std::uint8_t* data, std::size_t n);

/// n zeros (a sparse cube mask: a few pixels set in every frame) by zeroSparse for more than 64 MiB (else
/// prefaultedZeros). The hot pixels' mask of 1500 x 512^2 (393 MB for 20 pixels a frame) took 1.1 CPU-s of
/// the kernel's page clearing when written whole on the 2-core dev VM.
MaskVector sparseZeros(std::size_t n);

}  // namespace st

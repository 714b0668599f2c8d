#pragma once
// A zeroed vector for a whole cube (or its mask), allocated without paying its page faults on one core.
#include <cstddef>
#include <cstdint>
#include <vector>

namespace st {

/// n zeros (std::vector's value-initialisation). On Linux the pages of a large buffer (> 64 MiB) are first
/// populated by the kernel on parallelFor's threads (madvise MADV_POPULATE_WRITE, huge pages where allowed),
/// so the vector's single-threaded zero fill runs at memory speed instead of one page fault per 4 KiB;
/// elsewhere, or on a kernel without it (< 5.14), a plain vector. The contents are those of
/// std::vector<T>(n).
std::vector<float> prefaultedZeros(std::size_t n, float);
std::vector<std::uint8_t> prefaultedZeros(std::size_t n, std::uint8_t);

}  // namespace st

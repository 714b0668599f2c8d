#pragma once
// A host vector for a whole cube, allocated without paying its page faults on one core.
#include <cstddef>
#include <vector>

namespace st::gpu {

/// n zero floats (std::vector's value-initialisation). On Linux the pages are first populated by the kernel
/// on several threads (madvise MADV_POPULATE_WRITE, huge pages where allowed), so the vector's
/// single-threaded zero fill runs at memory speed instead of one page fault per 4 KiB; elsewhere, or on a
/// kernel without it (< 5.14), a plain vector. For the filtered cube the matched filter downloads into.
std::vector<float> prefaultedFloats(std::size_t n);

}  // namespace st::gpu

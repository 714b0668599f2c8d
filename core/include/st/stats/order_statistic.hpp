#pragma once
// An exact k-th smallest of a large float array, in parallel: the medians and quantiles of whole frames
// and stacks (the matched filter's MAD sigma over ~16M samples, the PSF's robust statistics, the cosmic-ray
// tail) were serial std::nth_element calls on the main thread while the other threads waited.
#include <cstddef>

namespace st::stats {

/// The value std::nth_element(v, v + k, v + n) leaves at v[k], without touching v: a radix select over the
/// floats' order-preserving 32-bit keys, two 16-bit digits, each digit's histogram counted on the worker
/// threads (parallelFor). Small arrays (n < 65536) are copied and selected with std::nth_element instead.
/// -0 and +0 compare equal as in nth_element: when the k-th value is a zero, +0 is returned. Infinities and
/// denormals are ordered as by operator<. Precondition: no NaN in v (nth_element's order is undefined with
/// them; here a NaN is sorted by its bits, below -inf or above +inf, and the result is some value of v).
/// Throws InputError when k >= n. `maxThreads` caps the threads (0: workerCount()); 1 selects on the calling
/// thread alone (still a radix select: ~5x nth_element's speed at 2^18 values), for callers that run many
/// selections in parallel themselves.
float kthSmallest(const float* v, std::size_t n, std::size_t k, unsigned maxThreads = 0);

}  // namespace st::stats

#include "st/stats/order_statistic.hpp"

#include <algorithm>
#include <bit>
#include <cstdint>
#include <string>
#include <vector>

#include "st/common/error.hpp"
#include "st/common/parallel.hpp"

namespace st::stats {
namespace {

// Below this, starting the threads and clearing the histograms costs more than nth_element on a copy.
constexpr std::size_t kSerialBelow = std::size_t(1) << 16;
constexpr int kDigitBits = 16;
constexpr std::size_t kBins = std::size_t(1) << kDigitBits;
constexpr std::uint32_t kSign = 0x80000000u;
// A task's histogram counts in 32 bits (256 KiB of them, which stay in L2), so no task gets more elements.
constexpr std::size_t kMaxTaskElements = std::size_t(0xFFFFFFFFu);

// The float's bits made an unsigned key that orders as the floats do: positives get the sign bit set,
// negatives are negated (two's complement) so that larger magnitudes come lower. Negating rather than the
// usual bitwise not maps -0 (0x80000000) onto +0's key: the two zeros are one value, as nth_element's
// operator< sees them, and a rank among many zeros of both signs cannot fall between two keys.
inline std::uint32_t keyOf(float f) {
  const auto u = std::bit_cast<std::uint32_t>(f);
  return (u & kSign) ? 0u - u : u | kSign;
}

// keyOf's inverse (+0 for the zeros' key).
inline float valueOf(std::uint32_t key) {
  return std::bit_cast<float>((key & kSign) ? key & ~kSign : 0u - key);
}

// The bin of `total` holding rank *k (counting from the lowest bin); *k becomes the rank inside that bin.
std::uint32_t binOfRank(const std::vector<std::uint64_t>& total, std::size_t* k) {
  std::size_t below = 0;
  for (std::size_t b = 0; b < kBins; ++b) {
    if (*k < below + total[b]) {
      *k -= below;
      return static_cast<std::uint32_t>(b);
    }
    below += total[b];
  }
  // Unreachable: the bins count all n > k elements.
  throw Error("kthSmallest: the histogram lost elements");
}

}  // namespace

float kthSmallest(const float* v, std::size_t n, std::size_t k, unsigned maxThreads) {
  if (k >= n)
    throw InputError("kthSmallest: rank " + std::to_string(k) + " of " + std::to_string(n) +
                     " values (it must be below the count)");
  if (n < kSerialBelow) {
    std::vector<float> copy(v, v + n);
    std::nth_element(copy.begin(), copy.begin() + static_cast<std::ptrdiff_t>(k), copy.end());
    return copy[k];
  }
  // One contiguous slice and one histogram per worker thread: the counts are integers, so their sum is the
  // same whichever thread ran which slice and in what order.
  const unsigned threads = maxThreads > 0 ? std::min(maxThreads, workerCount()) : workerCount();
  std::size_t tasks = std::min<std::size_t>(threads, n / kSerialBelow);
  tasks = std::max(tasks, (n + kMaxTaskElements - 1) / kMaxTaskElements);
  const std::size_t slice = (n + tasks - 1) / tasks;
  std::vector<std::uint32_t> hist(tasks * kBins);
  std::vector<std::uint64_t> total(kBins);
  // Counts the keys of each slice that pass `select` into bins by `digit`, then sums the slices' bins.
  auto count = [&](auto select, auto digit) {
    parallelFor(tasks, 1, [&](std::size_t t0, std::size_t t1) {
      for (std::size_t t = t0; t < t1; ++t) {
        std::uint32_t* h = hist.data() + t * kBins;
        std::fill(h, h + kBins, 0u);
        const float* end = v + std::min(n, (t + 1) * slice);
        for (const float* p = v + t * slice; p < end; ++p) {
          const std::uint32_t key = keyOf(*p);
          if (select(key)) ++h[digit(key)];
        }
      }
    });
    parallelFor(
        kBins, kBins / 16,
        [&](std::size_t b0, std::size_t b1) {
          for (std::size_t b = b0; b < b1; ++b) {
            std::uint64_t s = 0;
            for (std::size_t t = 0; t < tasks; ++t)
              s += hist[t * kBins + b];
            total[b] = s;
          }
        },
        threads);
  };
  std::size_t rank = k;
  count([](std::uint32_t) { return true; }, [](std::uint32_t key) { return key >> kDigitBits; });
  const std::uint32_t high = binOfRank(total, &rank);
  // Second digit: only the keys in the high digit's bin, which hold ranks [k - rank, k - rank + its count).
  count([high](std::uint32_t key) { return (key >> kDigitBits) == high; },
        [](std::uint32_t key) { return key & std::uint32_t(kBins - 1); });
  const std::uint32_t low = binOfRank(total, &rank);
  return valueOf(high << kDigitBits | low);
}

}  // namespace st::stats

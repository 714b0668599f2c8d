// The parallel k-th smallest (stats/order_statistic.hpp). Oracle: std::nth_element on a copy, which the
// callers (the matched filter's MAD sigma, the PSF's robust statistics, the cosmic-ray tail) used before.
// Ranks are taken where an off-by-one shows: distinct values, and the first and last index of each run of
// equal values (zeros of both signs, infinities) in sorted order.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "st/common/error.hpp"
#include "st/stats/order_statistic.hpp"
#include "test_support.hpp"

namespace st::stats {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

float nthElement(std::vector<float> v, std::size_t k) {
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

// kthSmallest(v, k) against nth_element, and v left as it was (bit for bit). Zeros compare equal whatever
// their signs (as nth_element's operator< sees them); any other value must be nth_element's to the bit.
void expectKth(const std::vector<float>& v, std::size_t k, const std::string& what) {
  const std::vector<float> before = v;
  const float expected = nthElement(v, k);
  const float got = kthSmallest(v.data(), v.size(), k);
  if (expected == 0.0f) {
    EXPECT_EQ(got, 0.0f) << what << ", n " << v.size() << ", k " << k;
  } else {
    EXPECT_EQ(std::bit_cast<std::uint32_t>(got), std::bit_cast<std::uint32_t>(expected))
        << what << ", n " << v.size() << ", k " << k << ": " << got << " instead of " << expected;
  }
  EXPECT_EQ(std::memcmp(before.data(), v.data(), v.size() * sizeof(float)), 0) << what << ": input changed";
}

// Ranks 0, n/2, n - 1, a few random ones, and both ends of every run of equal values in sorted order
// (at most `maxRuns` runs, the rest sampled evenly).
std::vector<std::size_t> ranksOf(const std::vector<float>& v, std::mt19937& rng, std::size_t maxRuns = 16) {
  const std::size_t n = v.size();
  std::vector<std::size_t> ks = {0, n / 2, n - 1};
  std::uniform_int_distribution<std::size_t> any(0, n - 1);
  for (int i = 0; i < 4; ++i)
    ks.push_back(any(rng));
  std::vector<float> sorted = v;
  std::sort(sorted.begin(), sorted.end());
  std::vector<std::size_t> runStarts;
  for (std::size_t i = 1; i < n; ++i)
    if (sorted[i - 1] < sorted[i]) runStarts.push_back(i);
  const std::size_t step = std::max<std::size_t>(1, runStarts.size() / maxRuns);
  for (std::size_t r = 0; r < runStarts.size(); r += step) {
    ks.push_back(runStarts[r] - 1);
    ks.push_back(runStarts[r]);
  }
  return ks;
}

void expectAllRanks(const std::vector<float>& v, const std::string& what, std::size_t maxRuns = 16) {
  std::mt19937 rng(1);
  for (std::size_t k : ranksOf(v, rng, maxRuns))
    expectKth(v, k, what);
}

std::vector<float> normal(std::size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> g(0.0f, 1.0f);
  std::vector<float> v(n);
  for (auto& x : v)
    x = g(rng);
  return v;
}

// Sizes on both sides of the switch to the radix select (65536) and with slices of unequal lengths.
const std::size_t kSizes[] = {1, 2, 3, 100, 65535, 65536, 65537, std::size_t(1) << 20, 3'000'001};

TEST(OrderStatistic, NormalFloatsAtEverySize) {
  for (std::size_t n : kSizes)
    expectAllRanks(normal(n, static_cast<unsigned>(n)), "normal", 4);
}

TEST(OrderStatistic, EveryRankOfASmallAndALargeArray) {
  // Small: every rank. Large (radix path): every rank of a stretch around the median, where the two digits'
  // bins are the most crowded.
  const auto small = normal(1000, 7);
  for (std::size_t k = 0; k < small.size(); ++k)
    expectKth(small, k, "small");
  const auto large = normal(70'000, 8);
  std::vector<float> sorted = large;
  std::sort(sorted.begin(), sorted.end());
  for (std::size_t k = 34'000; k < 36'000; ++k)
    ASSERT_EQ(kthSmallest(large.data(), large.size(), k), sorted[k]) << "k " << k;
}

TEST(OrderStatistic, HeavyDuplicates) {
  for (std::size_t n : {std::size_t(1000), std::size_t(1) << 20, std::size_t(3'000'001)}) {
    std::mt19937 rng(static_cast<unsigned>(n));
    const float values[] = {-2.0f, -1.0f, 0.5f, 1.0f, 3.25f};
    std::uniform_int_distribution<int> pick(0, 4);
    std::vector<float> v(n);
    for (auto& x : v)
      x = values[pick(rng)];
    expectAllRanks(v, "five values");
  }
}

TEST(OrderStatistic, AllEqual) {
  for (std::size_t n : {std::size_t(5), std::size_t(1) << 20}) {
    expectAllRanks(std::vector<float>(n, 7.25f), "all 7.25");
    expectAllRanks(std::vector<float>(n, -3.0f), "all -3");
    expectAllRanks(std::vector<float>(n, -0.0f), "all -0");
  }
}

TEST(OrderStatistic, ZerosOfBothSignsAmongNegativesAndPositives) {
  // The zeros are one run of equal values in nth_element's order: every rank inside it must give a zero, and
  // the ranks just outside it the largest negative and the smallest positive.
  for (std::size_t n : {std::size_t(3000), std::size_t(1) << 20}) {
    std::mt19937 rng(static_cast<unsigned>(n) + 1);
    std::uniform_int_distribution<int> kind(0, 9);
    std::normal_distribution<float> g(0.0f, 1.0f);
    std::vector<float> v(n);
    for (auto& x : v) {
      const int c = kind(rng);
      x = c < 3 ? 0.0f : c < 6 ? -0.0f : c < 9 ? -std::fabs(g(rng)) : std::fabs(g(rng));
    }
    expectAllRanks(v, "zeros");
    const auto firstZero =
        static_cast<std::size_t>(std::count_if(v.begin(), v.end(), [](float x) { return x < 0; }));
    const auto zeros = static_cast<std::size_t>(std::count(v.begin(), v.end(), 0.0f));
    for (std::size_t k = firstZero; k < firstZero + zeros; k += std::max<std::size_t>(1, zeros / 50))
      expectKth(v, k, "inside the zeros");
    expectKth(v, firstZero + zeros - 1, "last zero");
    expectKth(v, firstZero + zeros, "above the zeros");
  }
}

TEST(OrderStatistic, Infinities) {
  for (std::size_t n : {std::size_t(500), std::size_t(1) << 20}) {
    auto v = normal(n, 11);
    for (std::size_t i = 0; i < n; i += 97)
      v[i] = -kInf;
    for (std::size_t i = 5; i < n; i += 89)
      v[i] = kInf;
    expectAllRanks(v, "infinities");
    EXPECT_EQ(kthSmallest(v.data(), n, 0), -kInf);
    EXPECT_EQ(kthSmallest(v.data(), n, n - 1), kInf);
  }
}

TEST(OrderStatistic, Denormals) {
  // Denormals of both signs (exponent bits 0), zeros and a few normal floats: the keys differ in the low
  // digit only, so the second pass decides.
  for (std::size_t n : {std::size_t(2000), std::size_t(1) << 20}) {
    std::mt19937 rng(static_cast<unsigned>(n) + 3);
    std::uniform_int_distribution<std::uint32_t> mantissa(0, 0x7FFFFF);
    std::uniform_int_distribution<int> kind(0, 19);
    std::vector<float> v(n);
    for (auto& x : v) {
      const int c = kind(rng);
      const std::uint32_t sign = c % 2 ? 0x80000000u : 0u;
      x = c == 0 ? 0.0f : c == 1 ? -0.0f : c == 2 ? 1e-30f : std::bit_cast<float>(sign | mantissa(rng));
    }
    const auto subnormals =
        std::count_if(v.begin(), v.end(), [](float x) { return std::fpclassify(x) == FP_SUBNORMAL; });
    ASSERT_GT(subnormals, static_cast<std::ptrdiff_t>(n / 2));
    expectAllRanks(v, "denormals");
  }
}

TEST(OrderStatistic, SortedAndReverseSorted) {
  for (std::size_t n : {std::size_t(1000), std::size_t(1) << 20}) {
    auto v = normal(n, 5);
    std::sort(v.begin(), v.end());
    expectAllRanks(v, "sorted");
    std::reverse(v.begin(), v.end());
    expectAllRanks(v, "reverse sorted");
  }
}

TEST(OrderStatistic, SameResultOnAnyNumberOfThreads) {
  // The slices (one a thread) and their histograms' merge are this machine's worker count otherwise; 3 and 7
  // slices leave a shorter last slice at 3'000'001.
  const auto v = normal(3'000'001, 13);
  std::mt19937 rng(2);
  const auto ks = ranksOf(v, rng, 4);
  std::vector<float> expected;
  for (std::size_t k : ks)
    expected.push_back(nthElement(v, k));
  for (const char* threads : {"1", "3", "7", "16"}) {
    const test::ScopedThreads scope(threads);
    for (std::size_t i = 0; i < ks.size(); ++i)
      EXPECT_EQ(kthSmallest(v.data(), v.size(), ks[i]), expected[i])
          << "ST_THREADS=" << threads << ", k " << ks[i];
  }
  // Capped by the caller (maxThreads: 1 = one slice on the calling thread).
  for (const unsigned cap : {1u, 2u, 5u})
    for (std::size_t i = 0; i < ks.size(); ++i)
      EXPECT_EQ(kthSmallest(v.data(), v.size(), ks[i], cap), expected[i])
          << "maxThreads " << cap << ", k " << ks[i];
}

TEST(OrderStatistic, RankOutOfRangeThrows) {
  const auto v = normal(100'000, 3);
  EXPECT_THROW(kthSmallest(v.data(), v.size(), v.size()), InputError);
  EXPECT_THROW(kthSmallest(v.data(), 10, 10), InputError);
  EXPECT_THROW(kthSmallest(v.data(), 0, 0), InputError);
}

TEST(OrderStatistic, NanDoesNotCrash) {
  // Outside the precondition: the result is unspecified, but nothing is read outside v.
  for (std::size_t n : {std::size_t(1000), std::size_t(1) << 17}) {
    auto v = normal(n, 17);
    for (std::size_t i = 0; i < n; i += 31)
      v[i] =
          (i / 31) % 2 ? std::numeric_limits<float>::quiet_NaN() : -std::numeric_limits<float>::quiet_NaN();
    for (std::size_t k : {std::size_t(0), n / 2, n - 1})
      EXPECT_NO_THROW(kthSmallest(v.data(), n, k));
  }
}

}  // namespace
}  // namespace st::stats

// parallelFor on its thread pool: every index once, nested and concurrent calls, errors, and that the pool's
// threads really run chunks and are reused between calls.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <mutex>
#include <random>
#include <set>
#include <string>
#include <thread>
#include <vector>

#ifdef __linux__
#include <sys/resource.h>

#include <cerrno>
#endif

#include "st/common/error.hpp"
#include "st/common/parallel.hpp"
#include "test_support.hpp"

namespace st {
namespace {

// A number of the running thread, never given to another thread (std::thread::id is not enough: glibc
// reuses the descriptor of a finished thread for the next one, so a new thread may have an old one's id).
int threadSerial() {
  static std::atomic<int> next{0};
  thread_local const int serial = next++;
  return serial;
}

// The threads other than the caller's that ran chunks of one call whose chunks each take `sleep`.
std::set<int> helpersOfOneCall(std::size_t chunks, std::chrono::milliseconds sleep) {
  std::mutex m;
  std::set<int> ids;
  parallelFor(chunks, 1, [&](std::size_t, std::size_t) {
    std::this_thread::sleep_for(sleep);
    std::lock_guard lock(m);
    ids.insert(threadSerial());
  });
  ids.erase(threadSerial());
  return ids;
}

TEST(Parallel, NestedCallsCoverEveryIndexOnce) {
  const test::ScopedThreads threads("4");
  std::vector<std::atomic<int>> hits(64 * 100);
  parallelFor(64, 1, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i)
      parallelFor(100, 3, [&](std::size_t b2, std::size_t e2) {
        for (std::size_t j = b2; j < e2; ++j)
          hits[i * 100 + j]++;
      });
  });
  for (auto& h : hits)
    ASSERT_EQ(h.load(), 1);
}

TEST(Parallel, ConcurrentCallersEachCoverTheirRange) {
  const test::ScopedThreads threads("3");
  constexpr int kCallers = 4, kCalls = 200, kN = 257;
  std::vector<std::vector<std::atomic<int>>> hits(kCallers);
  for (auto& h : hits)
    h = std::vector<std::atomic<int>>(kN);
  std::vector<std::thread> callers;
  for (int c = 0; c < kCallers; ++c)
    callers.emplace_back([&, c] {
      for (int k = 0; k < kCalls; ++k)
        parallelFor(kN, 5, [&](std::size_t b, std::size_t e) {
          for (std::size_t i = b; i < e; ++i)
            hits[c][i]++;
        });
    });
  for (auto& t : callers)
    t.join();
  for (const auto& h : hits)
    for (const auto& v : h)
      ASSERT_EQ(v.load(), kCalls);
}

TEST(Parallel, ErrorsPropagateFromNestedCallsAndThePoolGoesOn) {
  const test::ScopedThreads threads("4");
  EXPECT_THROW(parallelFor(8, 1,
                           [](std::size_t b, std::size_t) {
                             parallelFor(50, 1, [&](std::size_t b2, std::size_t) {
                               if (b == 5 && b2 == 17) throw InputError("boom");
                             });
                           }),
               InputError);
  std::atomic<std::size_t> sum{0};
  parallelFor(1000, 10, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i)
      sum += i;
  });
  EXPECT_EQ(sum.load(), 999u * 1000u / 2u);
}

// Threads of this process now (Linux: /proc/self/task), 0 where that cannot be read.
std::size_t processThreads() {
  std::size_t n = 0;
  std::error_code ec;
  for (auto it = std::filesystem::directory_iterator("/proc/self/task", ec);
       !ec && it != std::filesystem::directory_iterator(); it.increment(ec))
    ++n;
  return n;
}

TEST(Parallel, PoolThreadsRunChunksAndAreReusedBetweenCalls) {
  const test::ScopedThreads threads("4");
  // 8 chunks of 20 ms on 4 threads: helpers join within the first chunks' time.
  const auto helpers = helpersOfOneCall(8, std::chrono::milliseconds(20));
  EXPECT_GE(helpers.size(), 1u) << "no pool thread ran a chunk";
  EXPECT_LE(helpers.size(), 3u);  // ST_THREADS = 4 is the caller and 3 helpers
  const std::size_t after = processThreads();
  if (after == 0) GTEST_SKIP() << "no /proc/self/task";
  // The helpers outlive the call (a pool) and the next call starts none (idle ones may leave, never come).
  EXPECT_GE(after, 1 + helpers.size()) << "the helpers ended with the call: nothing is kept between calls";
  (void)helpersOfOneCall(8, std::chrono::milliseconds(5));
  EXPECT_LE(processThreads(), after) << "the second call started threads of its own";
}

#ifdef __linux__
// The nice values of the threads that ran the chunks of one call (each chunk sleeps so that helpers join).
std::set<int> niceOfChunks() {
  std::mutex m;
  std::set<int> nice;
  parallelFor(8, 1, [&](std::size_t, std::size_t) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    errno = 0;
    const int n = getpriority(PRIO_PROCESS, 0);
    const std::lock_guard lock(m);
    nice.insert(errno == 0 ? n : -100);
  });
  return nice;
}

TEST(Parallel, HelpersRunAtTheCallersPriority) {
  // The GUI's job thread runs at nice +5 and must not lend its threads to the GUI's own calls, nor borrow
  // theirs (an unprivileged thread cannot lower its nice value again).
  const test::ScopedThreads threads("4");
  const int own = getpriority(PRIO_PROCESS, 0);
  (void)niceOfChunks();  // pool threads at this thread's priority exist now
  std::set<int> lowered;
  std::thread([&] {
    ASSERT_EQ(setpriority(PRIO_PROCESS, 0, own + 5), 0);
    lowered = niceOfChunks();
  }).join();
  EXPECT_EQ(lowered, std::set<int>{own + 5});
  EXPECT_EQ(niceOfChunks(), std::set<int>{own});
}
#endif

TEST(Parallel, OneThreadRunsInOrderOnTheCaller) {
  const test::ScopedThreads threads("1");
  std::vector<std::size_t> order;
  const std::thread::id caller = std::this_thread::get_id();
  parallelFor(10, 3, [&](std::size_t b, std::size_t e) {
    EXPECT_EQ(std::this_thread::get_id(), caller);
    order.push_back(b);
    EXPECT_EQ(e, std::min<std::size_t>(10, b + 3));
  });
  EXPECT_EQ(order, (std::vector<std::size_t>{0, 3, 6, 9}));
}

TEST(Parallel, SortEqualsStdSortForATotalOrder) {
  const test::ScopedThreads threads("8");
  std::mt19937 rng(7);
  // Pairs (key, index): a total order whatever the keys' duplicates, as setCandidates' cell order.
  for (const std::size_t n : {0u, 1u, 4095u, 8192u, 8193u, 100000u, 130001u}) {
    std::vector<std::pair<int, int>> v(n);
    for (std::size_t i = 0; i < n; ++i)
      v[i] = {static_cast<int>(rng() % 50), static_cast<int>(i)};
    std::shuffle(v.begin(), v.end(), rng);
    auto expected = v;
    std::sort(expected.begin(), expected.end());
    parallelSort(v, std::less<>());
    ASSERT_EQ(v, expected) << n;
  }
  // Equivalent elements (keys only): sorted, the same multiset.
  std::vector<int> keys(50001);
  for (auto& k : keys)
    k = static_cast<int>(rng() % 7);
  auto expected = keys;
  std::sort(expected.begin(), expected.end(), std::greater<>());
  parallelSort(keys, std::greater<>());
  EXPECT_EQ(keys, expected);
}

}  // namespace
}  // namespace st

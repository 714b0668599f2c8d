// TimedParts and PartTimer (st/common/timed_parts.hpp): the one record of a stage's timed parts behind the
// pipeline's notes. Parts keep the order they were first timed in, a part timed again adds up, and the
// text gives each in milliseconds.
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "st/common/timed_parts.hpp"

namespace st {
namespace {

TEST(TimedParts, AddsUpByNameInFirstOrderAndFormatsMilliseconds) {
  TimedParts t;
  EXPECT_EQ(t.text(), "");
  EXPECT_EQ(t.seconds("stacks"), 0.0);
  t.add("stacks", 0.0125);
  t.add("links", 0.5);
  t.add("stacks", 0.0250);
  ASSERT_EQ(t.parts.size(), 2u);
  EXPECT_EQ(t.parts[0].name, "stacks");
  EXPECT_DOUBLE_EQ(t.seconds("stacks"), 0.0375);
  EXPECT_DOUBLE_EQ(t.seconds("links"), 0.5);
  EXPECT_EQ(t.text(), "stacks 37.5 ms, links 500.0 ms");
  t.add("busy", 0.010, 0.025);  // CPU time given: the cores it kept busy
  EXPECT_EQ(t.text(), "stacks 37.5 ms, links 500.0 ms, busy 10.0 ms (2.5 cores)");
}

TEST(TimedParts, TimerLapsEachPartFromThePreviousLap) {
  const auto start = std::chrono::steady_clock::now();
  TimedParts t;
  PartTimer timer(t);
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  const double first = timer.lap("first");
  const double second = timer.lap("second");
  std::this_thread::sleep_for(std::chrono::milliseconds(5));
  const double third = timer.lap("first");
  const double outer = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_GE(first, 0.019);
  EXPECT_GE(third, 0.004);
  EXPECT_DOUBLE_EQ(t.seconds("first"), first + third);
  EXPECT_DOUBLE_EQ(t.seconds("second"), second);
  // No time counted twice: the parts add up to at most the wall time around them.
  EXPECT_LE(first + second + third, outer);
  ASSERT_EQ(t.parts.size(), 2u);
  EXPECT_EQ(t.parts[1].name, "second");
  // Sleeping keeps no core busy: far less CPU than wall time.
  EXPECT_LT(t.parts[0].cpuSeconds, 0.5 * t.parts[0].seconds);
}

}  // namespace
}  // namespace st

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <thread>
#include <map>
#include <memory>
#include <random>
#include <vector>

#include "st/common/error.hpp"
#include "st/common/fits_header.hpp"
#include "st/common/frame_cube.hpp"
#include "st/common/memory_budget.hpp"
#include "st/common/parallel.hpp"
#include "st/common/prefault.hpp"
#include "st/common/sparse_bytes.hpp"
#include "st/common/timed_parts.hpp"
#include "st/common/trace.hpp"
#include "st/common/units.hpp"
#include "st/psf/moffat.hpp"

#include <nlohmann/json.hpp>

namespace st {
namespace {

TEST(Units, RoundTripsAndKnownValues) {
  // Paper §5.1: 5.97 deg/day at 0.305"/px (binned CHIMERA) is 5.97*3600/86400/0.305 = 0.8156 px/s.
  const double pxs = degPerDayToPxPerSec(5.97, 0.305);
  EXPECT_NEAR(pxs, 0.815574, 1e-6);
  EXPECT_NEAR(pxPerSecToDegPerDay(pxs, 0.305), 5.97, 1e-12);
  // 5"/s sky drift = 300"/min.
  EXPECT_NEAR(pxPerSecToArcsecPerMin(5.0 / 0.305, 0.305), 300.0, 1e-9);
  EXPECT_NEAR(arcsecPerMinToPxPerSec(300.0, 0.305), 5.0 / 0.305, 1e-12);
}

TEST(FrameCube, ConstructedZeroedEvenOnReusedMemory) {
  // The pixels' vector no longer zero-fills by itself (PixelVector): the constructor must, also where the
  // allocator hands back memory just freed (HeapReuseScope keeps large blocks in the heap) and above the
  // 64 MiB from which the pages are populated and zeroed on every core.
  const HeapReuseScope reuse;
  constexpr int kW = 4200, kH = 4200;  // 70.6 MB
  for (int round = 0; round < 2; ++round) {
    {
      auto dirty = std::make_unique<float[]>(static_cast<std::size_t>(kW) * kH + 1024);
      std::memset(dirty.get(), 0xff, (static_cast<std::size_t>(kW) * kH + 1024) * sizeof(float));
    }
    const FrameCube cube(kW, kH, 1);
    ASSERT_EQ(cube.pixels().size(), static_cast<std::size_t>(kW) * kH);
    std::size_t nonZero = 0;
    for (const float v : cube.pixels())
      nonZero += v != 0.0f;
    EXPECT_EQ(nonZero, 0u) << "round " << round;
  }
  // The mask's zeros (the hot-pixel stage's prefaultedZeros) likewise.
  for (int round = 0; round < 2; ++round) {
    {
      auto dirty = std::make_unique<std::uint8_t[]>(std::size_t{70} << 20);
      std::memset(dirty.get(), 0xff, std::size_t{70} << 20);
    }
    const MaskVector mask = prefaultedZeros((std::size_t{70} << 20) - 3, std::uint8_t{0});
    ASSERT_EQ(mask.size(), (std::size_t{70} << 20) - 3);
    EXPECT_EQ(std::count(mask.begin(), mask.end(), std::uint8_t{0}), static_cast<std::ptrdiff_t>(mask.size()))
        << "round " << round;
  }
  // The hot pixels' sparse mask: zeroSparse on a range of dirty memory that starts and ends off a page
  // boundary (its whole pages given back to the kernel, its partial end pages written): zeros inside, the
  // bytes around it untouched; then written where set. And sparseZeros, large and small.
  for (int round = 0; round < 3; ++round) {
    const std::size_t n = (std::size_t{5} << 20) + 1234 + static_cast<std::size_t>(round) * 4099;
    const std::size_t at = 3 + static_cast<std::size_t>(round) * 1001;
    std::vector<std::uint8_t> buf(n + at + 8192, 0xff);
    zeroSparse(buf.data() + at, n);
    EXPECT_EQ(std::count(buf.begin() + static_cast<std::ptrdiff_t>(at),
                         buf.begin() + static_cast<std::ptrdiff_t>(at + n), std::uint8_t{0}),
              static_cast<std::ptrdiff_t>(n))
        << "round " << round;
    EXPECT_EQ(std::count(buf.begin(), buf.begin() + static_cast<std::ptrdiff_t>(at), std::uint8_t{0xff}),
              static_cast<std::ptrdiff_t>(at));
    EXPECT_EQ(std::count(buf.begin() + static_cast<std::ptrdiff_t>(at + n), buf.end(), std::uint8_t{0xff}),
              static_cast<std::ptrdiff_t>(buf.size() - at - n));
    for (std::size_t i = at; i < at + n; i += 99991)
      buf[i] = 1;
    EXPECT_EQ(static_cast<std::size_t>(std::count(buf.begin(), buf.end(), std::uint8_t{1})),
              (n + 99990) / 99991);
  }
  for (const std::size_t n : {std::size_t{4099}, (std::size_t{70} << 20) - 3}) {
    const MaskVector mask = sparseZeros(n);
    ASSERT_EQ(mask.size(), n);
    EXPECT_EQ(std::count(mask.begin(), mask.end(), std::uint8_t{0}), static_cast<std::ptrdiff_t>(n));
  }
  const FrameCube small(3, 2, 2);
  for (const float v : small.pixels())
    EXPECT_EQ(v, 0.0f);
  const FrameCube over = FrameCube::forOverwrite(5, 4, 3);
  EXPECT_EQ(over.pixels().size(), 60u);
  EXPECT_EQ(over.frameCount(), 3u);
  EXPECT_THROW(FrameCube::forOverwrite(0, 4, 1), InputError);
}

TEST(FrameCube, ReferenceEpochIsMeanOfMidTimes) {
  FrameCube cube(4, 3, 3);
  cube.info()[0].mjdMid = 60000.0;
  cube.info()[1].mjdMid = 60000.0 + 1.0 / 86400.0;
  cube.info()[2].mjdMid = 60000.0 + 5.0 / 86400.0;
  EXPECT_NEAR(cube.tRefMjd(), 60000.0 + 2.0 / 86400.0, 1e-11);
  const auto dt = cube.timeOffsetsS();
  EXPECT_NEAR(dt[0], -2.0, 1e-5);
  EXPECT_NEAR(dt[2], 3.0, 1e-5);
  EXPECT_NEAR(cube.timeSpanS(), 5.0, 1e-5);
  EXPECT_EQ(cube.pixels().size(), 36u);
  EXPECT_THROW(FrameCube(0, 3, 1), InputError);
}

TEST(FitsHeader, QuotedNumbersAndBadValues) {
  FitsHeader h;
  h.setString("CDELT1", "0.000272");
  h.set("EXPTIME", "1.5D2");
  h.setString("OBJECT", "M31");
  EXPECT_NEAR(*h.getDouble("cdelt1"), 0.000272, 1e-15);
  EXPECT_NEAR(*h.getDouble("EXPTIME"), 150.0, 1e-12);
  EXPECT_FALSE(h.getDouble("NOPE").has_value());
  try {
    (void)h.getDouble("OBJECT");
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("OBJECT"), std::string::npos);
  }
}

TEST(Parallel, CoversRangeOnceAndPropagatesErrors) {
  std::vector<std::atomic<int>> hits(1000);
  parallelFor(hits.size(), 7, [&](std::size_t b, std::size_t e) {
    for (auto i = b; i < e; ++i)
      hits[i]++;
  });
  for (auto& h : hits)
    EXPECT_EQ(h.load(), 1);
  EXPECT_THROW(parallelFor(100, 1,
                           [](std::size_t b, std::size_t) {
                             if (b == 50) throw InputError("boom");
                           }),
               InputError);
}

// sparseBytes against a byte-by-byte scan: non-zero bytes at the ends of pieces (1 MiB) and of lines (64
// bytes), in a tail shorter than a line, every value 1..255; none above the limit, exactly at it found.
TEST(SparseBytes, EveryNonZeroByteInOrderAndNoneOverTheLimit) {
  const std::size_t n = (std::size_t{3} << 20) + 37;  // three pieces and a tail of 37 bytes
  std::vector<std::uint8_t> data(n, 0);
  std::mt19937_64 rng(7);
  for (std::size_t i : {std::size_t{0}, std::size_t{63}, std::size_t{64}, (std::size_t{1} << 20) - 1,
                        std::size_t{1} << 20, n - 37, n - 1})
    data[i] = 1;
  for (int k = 0; k < 3000; ++k)
    data[rng() % n] = static_cast<std::uint8_t>(1 + rng() % 255);
  std::vector<std::uint64_t> index;
  std::vector<std::uint8_t> value;
  for (std::size_t i = 0; i < n; ++i)
    if (data[i]) {
      index.push_back(i);
      value.push_back(data[i]);
    }
  const std::optional<SparseBytes> all = sparseBytes(data, index.size());
  ASSERT_TRUE(all.has_value());
  EXPECT_EQ(all->index, index);
  EXPECT_EQ(all->value, value);
  EXPECT_FALSE(sparseBytes(data, index.size() - 1).has_value());
  const std::vector<std::uint8_t> zeros(1000, 0);
  const std::optional<SparseBytes> none = sparseBytes(zeros, 0);
  ASSERT_TRUE(none.has_value());
  EXPECT_TRUE(none->index.empty());
  EXPECT_TRUE(sparseBytes({}, 0).has_value());
}

TEST(Moffat, FwhmAndIntegralsMatchClosedForms) {
  psf::Moffat m{3.3, 4.0};
  EXPECT_NEAR(m(m.fwhm() / 2.0, 0.0), 0.5, 1e-12);
  EXPECT_NEAR(psf::Moffat::radiusForFwhm(m.fwhm(), 4.0), 3.3, 1e-12);
  double sum = 0.0, sum2 = 0.0;
  for (int y = -200; y <= 200; ++y)
    for (int x = -200; x <= 200; ++x) {
      const double p = m(x, y);
      sum += p;
      sum2 += p * p;
    }
  EXPECT_NEAR(sum / m.integral(), 1.0, 2e-3);
  EXPECT_NEAR(sum2 / m.integralOfSquare(), 1.0, 2e-3);
}

}  // namespace
}  // namespace st

namespace st {
namespace {

// The trace (ST_TRACE) records scopes and PartTimer laps from every thread with their real times, and its
// file is valid JSON with the Chrome trace fields Perfetto reads.
TEST(Trace, RecordsScopesAndLapsOfEveryThreadAsChromeEvents) {
  const std::filesystem::path path = std::filesystem::temp_directory_path() / "st_test_trace.json";
  trace::stop();
  {
    const trace::Scope before("before start");  // not recorded: off
  }
  trace::start(path.string());
  ASSERT_TRUE(trace::enabled());
  {
    const trace::Scope scope("outer \"quoted\"");
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  std::thread other([] { const trace::Scope scope("on another thread"); });
  other.join();
  TimedParts parts;
  PartTimer timer(parts);
  std::this_thread::sleep_for(std::chrono::milliseconds(5));
  timer.lap("a lap");
  EXPECT_EQ(trace::flush(), 3u);
  trace::stop();
  EXPECT_FALSE(trace::enabled());
  EXPECT_EQ(trace::flush(), 0u);

  std::ifstream in(path);
  const nlohmann::json j = nlohmann::json::parse(in);
  const auto& events = j.at("traceEvents");
  ASSERT_EQ(events.size(), 3u);
  std::map<std::string, nlohmann::json> byName;
  for (const auto& e : events) {
    EXPECT_EQ(e.at("ph"), "X");
    byName[e.at("name").get<std::string>()] = e;
  }
  ASSERT_EQ(byName.count("outer \"quoted\""), 1u);
  ASSERT_EQ(byName.count("on another thread"), 1u);
  ASSERT_EQ(byName.count("a lap"), 1u);
  const auto& outer = byName["outer \"quoted\""];
  EXPECT_GE(outer.at("dur").get<double>(), 19000.0);  // microseconds
  EXPECT_NE(outer.at("tid"), byName["on another thread"].at("tid"));
  EXPECT_GE(byName["a lap"].at("dur").get<double>(), 4000.0);
  // In order: the lap began after the scope ended.
  EXPECT_GE(byName["a lap"].at("ts").get<double>(),
            outer.at("ts").get<double>() + outer.at("dur").get<double>() - 1.0);
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace st

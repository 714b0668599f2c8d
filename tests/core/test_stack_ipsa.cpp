// IPSA stack (paper §2.1, ARCHITECTURE.md conventions) against a brute-force loop.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <thread>

#include "st/common/error.hpp"
#include "st/common/frame_cube.hpp"
#include "st/stack/ipsa.hpp"

namespace st::stack {
namespace {

/// Random frames at random, non-uniform mid-times (gaps of 0.05..0.5 s).
FrameCube randomCube(int w, int h, std::size_t n, unsigned seed) {
  FrameCube cube(w, h, n);
  std::mt19937 rng(seed);
  std::normal_distribution<float> g(0.0f, 1.0f);
  std::uniform_real_distribution<double> gap(0.05, 0.5);
  for (auto& p : cube.pixels())
    p = g(rng);
  double t = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    t += gap(rng);
    cube.info()[i].mjdMid = 60123.25 + t / 86400.0;
  }
  return cube;
}

/// The definition, pixel by pixel, frames in order n = 0, 1, ... (the same float additions).
StackResult bruteForce(const FrameCube& cube, Velocity v) {
  const auto dt = cube.timeOffsetsS();
  StackResult r;
  r.sum = Image(cube.width(), cube.height());
  r.nIn.assign(cube.framePixels(), 0);
  for (int y = 0; y < cube.height(); ++y)
    for (int x = 0; x < cube.width(); ++x) {
      float s = 0.0f;
      int count = 0;
      for (std::size_t n = 0; n < cube.frameCount(); ++n) {
        const int sx = x + int(std::round(v.vx * dt[n])), sy = y + int(std::round(v.vy * dt[n]));
        if (sx < 0 || sy < 0 || sx >= cube.width() || sy >= cube.height()) continue;
        s += cube.frame(n)[sy * cube.width() + sx];
        ++count;
      }
      r.sum.at(x, y) = s;
      r.nIn[std::size_t(y) * cube.width() + x] = std::uint16_t(count);
    }
  return r;
}

TEST(Ipsa, EqualsBruteForceOnRandomDataWithNonUniformTimes) {
  const FrameCube cube = randomCube(67, 45, 40, 1);
  for (const Velocity v : {Velocity{0, 0}, Velocity{1.37, -0.61}, Velocity{-4.9, 2.2}, Velocity{30.0, 0.4},
                           Velocity{0.0, -9.5}, Velocity{500.0, 500.0}}) {
    const StackResult fast = stackIpsa(cube, v);
    const StackResult ref = bruteForce(cube, v);
    ASSERT_EQ(fast.sum.pixels.size(), ref.sum.pixels.size());
    for (std::size_t i = 0; i < ref.sum.pixels.size(); ++i) {
      ASSERT_EQ(fast.sum.pixels[i], ref.sum.pixels[i]) << "pixel " << i << " v " << v.vx << "," << v.vy;
      ASSERT_EQ(fast.nIn[i], ref.nIn[i]) << "pixel " << i;
    }
    EXPECT_EQ(fast.velocity, v);
    EXPECT_DOUBLE_EQ(fast.tRefMjd, cube.tRefMjd());
  }
}

// An object at (x0, y0) at t_ref moving at v is at x0 + v (t_n - t_ref) in frame n (rounded to the pixel it
// lands on): the stack at v collects all its flux at (x0, y0), and N_in there is the frame count.
TEST(Ipsa, MovingPointSourceStacksAtItsReferencePosition) {
  FrameCube cube = randomCube(80, 60, 50, 2);
  for (auto& p : cube.pixels())
    p = 0.0f;
  const Velocity v{2.3, -0.8};
  const auto dt = cube.timeOffsetsS();
  for (std::size_t n = 0; n < 50; ++n) {
    const int x = 40 + int(std::round(v.vx * dt[n])), y = 30 + int(std::round(v.vy * dt[n]));
    cube.frame(n)[y * 80 + x] = 1.0f;
  }
  const StackResult s = stackIpsa(cube, v);
  EXPECT_FLOAT_EQ(s.sum.at(40, 30), 50.0f);
  EXPECT_EQ(s.nIn[30 * 80 + 40], 50);
  EXPECT_LT(stackIpsa(cube, Velocity{0, 0}).sum.at(40, 30), 5.0f);
}

TEST(Ipsa, ConcurrentCallsGiveTheSameResult) {
  const FrameCube cube = randomCube(96, 64, 60, 3);
  const Velocity v{3.3, 1.1};
  const StackResult ref = stackIpsa(cube, v);
  std::vector<StackResult> out(4);
  std::vector<std::thread> threads;
  for (int i = 0; i < 4; ++i)
    threads.emplace_back([&, i] { out[std::size_t(i)] = stackIpsa(cube, v); });
  for (auto& t : threads)
    t.join();
  for (const auto& r : out) {
    EXPECT_EQ(r.sum.pixels, ref.sum.pixels);
    EXPECT_EQ(r.nIn, ref.nIn);
  }
}

TEST(Ipsa, BadInput) {
  EXPECT_THROW((void)stackIpsa(FrameCube(), Velocity{}), InputError);
  const FrameCube cube = randomCube(8, 8, 3, 4);
  EXPECT_THROW((void)stackIpsa(cube, std::vector<double>{0.0, 1.0}, Velocity{}), InputError);
}

}  // namespace
}  // namespace st::stack

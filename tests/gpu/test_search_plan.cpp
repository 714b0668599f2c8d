// The CUDA backend's host-side plan (gpu/src/search_plan.hpp) against brute force: for every velocity and
// every column (row), the kernels sum the time-ordered frames [lo, hi] of its span, which must be exactly
// the frames whose shift keeps that column inside the frame; shifts are IPSA's rounding. Host code only:
// runs without a device.
#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>

#include "gpu_test_cubes.hpp"
#include "search_plan.hpp"

namespace st {
namespace {

/// Checks one axis: shifts [nv][N] in frame order, spans [nv][extent][2] over time-ordered frames.
void expectSpansMatchBruteForce(const std::vector<int>& shifts, const std::vector<int>& spans, int nv,
                                int extent, const std::vector<int>& timeOrder) {
  const int n = static_cast<int>(timeOrder.size());
  for (int i = 0; i < nv; ++i) {
    for (int c = 0; c < extent; ++c) {
      const int lo = spans[(static_cast<std::size_t>(i) * extent + c) * 2];
      const int hi = spans[(static_cast<std::size_t>(i) * extent + c) * 2 + 1];
      for (int k = 0; k < n; ++k) {
        const int s = shifts[static_cast<std::size_t>(i) * n + timeOrder[k]];
        const bool inside = c + s >= 0 && c + s < extent;
        ASSERT_EQ(inside, k >= lo && k <= hi) << "velocity " << i << " column " << c << " frame " << k;
      }
    }
  }
}

TEST(SearchPlan, SpansAreExactlyTheFramesKeepingEachColumnInside) {
  // Shifts from -70 to +70 px over a 61 x 47 frame: columns leave on both sides, some velocities keep
  // every frame, some none; times uneven and two frames out of order.
  test::CubeTiming timing;
  timing.cadenceS = 0.5;
  timing.jitterS = 0.2;
  timing.gapAfter = 20;
  timing.gapS = 3.0;
  const search::FilteredCube cube = test::movingPointsCube(61, 47, 41, 5u, timing, {}, 2.0);
  const search::VelocityGrid grid{{0.4, -0.3}, 0.45, 13, 11};
  const gpu::HostPlan plan = gpu::makeHostPlan(cube, grid, 5.0, 1);
  const std::vector<double> dt = cube.frames.timeOffsetsS();
  std::vector<int> order(dt.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return dt[a] < dt[b]; });
  for (int i = 0; i < grid.nvx; ++i) {
    for (std::size_t k = 0; k < dt.size(); ++k)
      ASSERT_EQ(plan.shiftX[i * dt.size() + k], search::ipsaShift(grid.at(i, 0).vx, dt[k]));
  }
  expectSpansMatchBruteForce(plan.shiftX, plan.spanX, grid.nvx, 61, order);
  expectSpansMatchBruteForce(plan.shiftY, plan.spanY, grid.nvy, 47, order);
}

}  // namespace
}  // namespace st

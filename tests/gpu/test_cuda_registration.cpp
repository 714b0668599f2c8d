// The CUDA backend on registered frames (issue 15, item 1): frames carrying registration offsets o_n
// (non-integer, up to +-6 px, so the shifts round(o_n + v dt_n) are not monotone in time and N_in comes from
// the per-frame masks) give the CPU backends' results: the exact search on every kernel (tiled, row, stair,
// naive) the CPU exact search's and the plain host reference's, the tree search the CPU tree's, and stackAt
// the CPU IPSA stack. Every test skips when no CUDA device is usable.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "gpu_test_cubes.hpp"
#include "ipsa_host_reference.hpp"
#include "st/gpu/cuda_backend.hpp"
#include "st/search/cpu_backend.hpp"
#include "st/search/tree_search.hpp"
#include "st/stack/ipsa.hpp"

namespace st {
namespace {

using search::FilteredCube;
using search::SearchParams;
using search::SearchResult;
using search::VelocityGrid;

void addOffsets(FrameCube& cube, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-6.0, 6.0);
  for (auto& f : cube.info()) {
    f.offsetXPx = u(rng);
    f.offsetYPx = u(rng);
  }
}

struct Problem {
  FilteredCube cube;
  VelocityGrid grid;
  SearchParams params;
};

/// As test_cuda_backend.cpp's problems (uneven, unsorted times, a moving source), with offsets.
Problem registeredProblem(bool fineGrid, bool tree) {
  test::CubeTiming timing;
  timing.cadenceS = 0.06;
  timing.jitterS = 0.02;
  timing.gapAfter = 18;
  timing.gapS = 1.0;
  timing.swapped = {1, 4};
  Problem p;
  p.grid = fineGrid ? VelocityGrid{{3.0, -2.0}, 0.4, 19, 7} : VelocityGrid{{3.0, -2.0}, 1.5, 9, 7};
  p.cube =
      test::movingPointsCube(fineGrid ? 64 : 61, 47, 37, 7u, timing, {{30, 20, p.grid.at(6, 2), 1.6f}}, 2.5);
  addOffsets(p.cube.frames, 99);
  p.params.snrThreshold = 3.5;
  p.params.maxCandidates = 100000;
  p.params.minFrameFraction = 0.5;
  if (tree) p.params.method = st::search::SearchMethod::Tree;
  return p;
}

void expectSame(const SearchResult& g, const SearchResult& c) {
  ASSERT_EQ(g.map.maxSnr.size(), c.map.maxSnr.size());
  for (std::size_t iv = 0; iv < c.map.maxSnr.size(); ++iv) {
    EXPECT_NEAR(g.map.maxSnr[iv], c.map.maxSnr[iv], 1e-4 * std::max(1.0f, std::abs(c.map.maxSnr[iv]))) << iv;
    EXPECT_EQ(g.map.argX[iv] < 0, c.map.argX[iv] < 0) << iv;
  }
  EXPECT_EQ(g.cellsAboveThreshold, c.cellsAboveThreshold);
  EXPECT_GT(c.cellsAboveThreshold, 0);
  ASSERT_EQ(g.candidates.size(), c.candidates.size());
  for (std::size_t i = 0; i < c.candidates.size(); ++i) {
    EXPECT_EQ(g.candidates[i].x, c.candidates[i].x) << i;
    EXPECT_EQ(g.candidates[i].y, c.candidates[i].y) << i;
    EXPECT_EQ(g.candidates[i].nIn, c.candidates[i].nIn) << i;
    EXPECT_NEAR(g.candidates[i].snr, c.candidates[i].snr, 1e-4 * c.candidates[i].snr) << i;
  }
}

void checkExact(gpu::ExactKernel kernel, bool fineGrid) {
  gpu::CudaOptions o;
  o.exactKernel = kernel;
  ST_REQUIRE_GPU(gpu, o);
  const Problem p = registeredProblem(fineGrid, false);
  ASSERT_TRUE(p.cube.frames.hasFrameOffsets());
  NullProgress progress;
  CancelToken cancel;
  const SearchResult g = gpu->search(p.cube, p.grid, p.params, progress, cancel);
  const SearchResult c = search::makeCpuBackend()->search(p.cube, p.grid, p.params, progress, cancel);
  expectSame(g, c);
  // And the plain host reference (round(o_n + v dt_n), N_in counted frame by frame).
  const test::RefSearch ref = test::refSearch(p.cube, p.grid, p.params.snrThreshold, g.minFrames);
  for (std::size_t iv = 0; iv < p.grid.count(); ++iv)
    EXPECT_NEAR(g.map.maxSnr[iv], ref.mapSnr[iv], 1e-4 * std::max(1.0, std::abs(ref.mapSnr[iv]))) << iv;
  EXPECT_EQ(g.cellsAboveThreshold, static_cast<std::int64_t>(ref.cells.size()));
}

TEST(CudaRegistration, TiledKernelGivesTheCpuResult) {
  checkExact(gpu::ExactKernel::Tiled, false);
}

TEST(CudaRegistration, RowKernelGivesTheCpuResult) {
  checkExact(gpu::ExactKernel::Row, true);
}

TEST(CudaRegistration, StairKernelGivesTheCpuResult) {
  checkExact(gpu::ExactKernel::Auto, true);
}

TEST(CudaRegistration, StairKernel4RowsGivesTheCpuResult) {
  checkExact(gpu::ExactKernel::StairFourRows, true);
}

TEST(CudaRegistration, NaiveKernelGivesTheCpuResult) {
  checkExact(gpu::ExactKernel::Naive, false);
}

TEST(CudaRegistration, TreeGivesTheCpuTreesResult) {
  for (const int cut : {1, 4}) {
    gpu::CudaOptions o;
    o.treeCut = cut;
    ST_REQUIRE_GPU(gpu, o);
    const Problem p = registeredProblem(true, true);
    NullProgress progress;
    CancelToken cancel;
    const SearchResult g = gpu->search(p.cube, p.grid, p.params, progress, cancel);
    const SearchResult c = search::treeSearch(p.cube, p.grid, p.params, progress, cancel);
    EXPECT_EQ(g.method, st::search::SearchMethod::Tree);
    SCOPED_TRACE("cut " + std::to_string(cut));
    expectSame(g, c);
  }
}

TEST(CudaRegistration, StackAtUsesTheOffsets) {
  ST_REQUIRE_GPU(gpu);
  const Problem p = registeredProblem(false, false);
  for (const Velocity v : {Velocity{0.0, 0.0}, Velocity{7.3, -4.6}}) {
    const Image g = gpu->stackAt(p.cube, v, search::StackMode::Ipsa);
    const stack::StackResult c = stack::stackIpsa(p.cube.frames, v);
    const Image r = test::refStack(p.cube.frames, v, false);
    double worst = 0.0, worstRef = 0.0;
    for (std::size_t i = 0; i < c.sum.pixels.size(); ++i) {
      worst = std::max(worst, double(std::abs(g.pixels[i] - c.sum.pixels[i])));
      worstRef = std::max(worstRef, double(std::abs(g.pixels[i] - r.pixels[i])));
    }
    EXPECT_LT(worst, 2e-5 * 37);
    EXPECT_LT(worstRef, 2e-5 * 37);
  }
}

}  // namespace
}  // namespace st

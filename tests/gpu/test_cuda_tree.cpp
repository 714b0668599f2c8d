// The CUDA tree search (method "tree") against the CPU tree search (core/search/tree_search.cpp) on the same
// cubes: the GPU forms every partial stack in the CPU's order, so the velocity map must be equal (SNR within
// 1e-6 relative, same argmax), the count of cells above threshold equal, and the candidates the same cells
// with SNR within 1e-4 relative and the same N_in and cluster sizes. Cubes have uneven, unsorted frame times
// with a gap, sources moving out of the frame (N_in below N_f), and are run whole, in small tiles of rows
// (tile height not dividing the image), and with 1 to 4 top levels summed in registers. Every test skips
// when no CUDA device is usable.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "gpu_test_cubes.hpp"
#include "st/common/error.hpp"
#include "st/gpu/cuda_backend.hpp"
#include "st/search/ipsa.hpp"
#include "st/search/tree_search.hpp"

namespace st {
namespace {

using search::FilteredCube;
using search::SearchParams;
using search::SearchResult;
using search::VelocityGrid;

/// Noise (sigma 1), uneven cadence with a gap, two frames out of time order, and sources moving across
/// (one of them leaves the frame half-way).
FilteredCube makeCube(int w, int h, int n, unsigned seed) {
  test::CubeTiming timing;
  timing.cadenceS = 0.1;
  timing.jitterS = 0.03;
  timing.gapAfter = n / 3;
  timing.gapS = 0.8;
  timing.swapped = {2, 5};
  return test::movingPointsCube(
      w, h, n, seed, timing,
      {{30, 40, {4.0, -3.0}, 1.5f}, {w - 6, 10, {9.0, 2.5}, 2.0f}, {50, 20, {-1.0, 5.5}, 1.2f}}, 2.0);
}

struct Problem {
  FilteredCube cube;
  VelocityGrid grid;
  SearchParams params;
};

Problem standardProblem() {
  Problem p{makeCube(96, 70, 64, 11), VelocityGrid{{3.0, 1.0}, 0.35, 37, 31}, {}};
  p.params.method = st::search::SearchMethod::Tree;
  p.params.snrThreshold = 4.5;
  p.params.minFrameFraction = 0.3;
  return p;
}

void expectSameAsCpuTree(const SearchResult& g, const Problem& p) {
  NullProgress progress;
  CancelToken cancel;
  const SearchResult c = search::treeSearch(p.cube, p.grid, p.params, progress, cancel);
  EXPECT_EQ(g.method, st::search::SearchMethod::Tree);
  ASSERT_EQ(g.map.maxSnr.size(), c.map.maxSnr.size());
  for (std::size_t iv = 0; iv < c.map.maxSnr.size(); ++iv) {
    EXPECT_NEAR(g.map.maxSnr[iv], c.map.maxSnr[iv], 1e-6 * std::max(1.0f, std::abs(c.map.maxSnr[iv]))) << iv;
    EXPECT_EQ(g.map.argX[iv], c.map.argX[iv]) << iv;
    EXPECT_EQ(g.map.argY[iv], c.map.argY[iv]) << iv;
  }
  EXPECT_EQ(g.cellsAboveThreshold, c.cellsAboveThreshold);
  EXPECT_GT(c.cellsAboveThreshold, 0);
  EXPECT_EQ(g.minFrames, c.minFrames);
  EXPECT_EQ(g.snrThreshold, c.snrThreshold);
  ASSERT_EQ(g.candidates.size(), c.candidates.size());
  bool partial = false;
  for (std::size_t i = 0; i < c.candidates.size(); ++i) {
    const auto& a = g.candidates[i];
    const auto& b = c.candidates[i];
    EXPECT_EQ(a.x, b.x) << i;
    EXPECT_EQ(a.y, b.y) << i;
    EXPECT_EQ(a.ivx, b.ivx) << i;
    EXPECT_EQ(a.ivy, b.ivy) << i;
    EXPECT_EQ(a.nIn, b.nIn) << i;
    EXPECT_EQ(a.clusterCells, b.clusterCells) << i;
    EXPECT_NEAR(a.snr, b.snr, 1e-4 * std::abs(b.snr)) << i;
    partial = partial || b.nIn < static_cast<int>(p.cube.frames.frameCount());
  }
  EXPECT_TRUE(partial) << "no candidate at a frame edge: the test does not exercise N_in";
}

TEST(CudaTree, WholeImageGivesTheCpuTreesResult) {
  ST_REQUIRE_GPU(gpu);
  const Problem p = standardProblem();
  NullProgress progress;
  CancelToken cancel;
  const SearchResult g = gpu->search(p.cube, p.grid, p.params, progress, cancel);
  expectSameAsCpuTree(g, p);
  EXPECT_NE(gpu->lastNote().find("tree"), std::string::npos) << gpu->lastNote();
  EXPECT_GT(gpu->lastTreeAdditions(), 0.0);
  // The brightest injected source is the best candidate, at its position and near its velocity.
  ASSERT_FALSE(g.candidates.empty());
  EXPECT_NEAR(g.candidates.front().x, 30, 2);
  EXPECT_NEAR(g.candidates.front().y, 40, 2);
}

TEST(CudaTree, SmallTilesAndEveryCutGiveTheCpuTreesResult) {
  const Problem p = standardProblem();
  for (const int cut : {1, 2, 4}) {
    for (const int rows : {0, 7, 1}) {
      gpu::CudaOptions o;
      o.treeCut = cut;
      o.treeTileRows = rows;
      ST_REQUIRE_GPU(gpu, o);
      NullProgress progress;
      CancelToken cancel;
      SCOPED_TRACE("cut " + std::to_string(cut) + ", tile rows " + std::to_string(rows));
      expectSameAsCpuTree(gpu->search(p.cube, p.grid, p.params, progress, cancel), p);
    }
  }
}

TEST(CudaTree, EveryRootKernelShapeGivesTheCpuTreesResult) {
  const Problem p = standardProblem();
  for (const int shape : {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13}) {
    gpu::CudaOptions o;
    o.treeTileRows = 19;
    gpu::CudaBenchOptions b;
    b.treeRootShape = shape;
    ST_REQUIRE_GPU(gpu, o, b);
    NullProgress progress;
    CancelToken cancel;
    SCOPED_TRACE("root shape " + std::to_string(shape));
    expectSameAsCpuTree(gpu->search(p.cube, p.grid, p.params, progress, cancel), p);
  }
}

TEST(CudaTree, MemoryLimitTilesTheRowsOrFailsClearly) {
  const Problem p = standardProblem();
  gpu::CudaOptions o;
  o.cellCapacity = 65536;  // 2 MiB of cells; with 3 levels in registers the whole image's partial stacks
  o.treeCut = 3;           // need ~42 MB, tiles of 12 rows ~8 MB
  o.deviceMemoryLimitBytes = p.cube.frames.pixels().size() * 4 + (std::size_t{14} << 20);
  ST_REQUIRE_GPU(gpu, o);
  NullProgress progress;
  CancelToken cancel;
  expectSameAsCpuTree(gpu->search(p.cube, p.grid, p.params, progress, cancel), p);
  EXPECT_EQ(gpu->lastNote().find("tiles 0..0 "), std::string::npos) << gpu->lastNote();
  gpu::CudaOptions tiny;
  tiny.cellCapacity = 65536;
  tiny.deviceMemoryLimitBytes = 1 << 20;
  auto small = test::cudaOrNull(tiny);
  EXPECT_THROW(small->search(p.cube, p.grid, p.params, progress, cancel), GpuError);
}

TEST(CudaTree, CoarseGridsWithDirectNodesNearTheRoot) {
  // One or three velocities: nodes just below the root hold a single velocity and are summed from their
  // frames, so fewer levels can be summed in registers.
  for (const auto& grid : {VelocityGrid{{2.0, 1.0}, 0.5, 1, 1}, VelocityGrid{{2.0, 1.0}, 0.5, 3, 1}}) {
    ST_REQUIRE_GPU(gpu);
    Problem p = standardProblem();
    p.grid = grid;
    p.params.snrThreshold = 3.0;
    NullProgress progress;
    CancelToken cancel;
    const SearchResult g = gpu->search(p.cube, p.grid, p.params, progress, cancel);
    const SearchResult c = search::treeSearch(p.cube, p.grid, p.params, progress, cancel);
    ASSERT_EQ(g.map.maxSnr, c.map.maxSnr);
    EXPECT_EQ(g.map.argX, c.map.argX);
    EXPECT_EQ(g.map.argY, c.map.argY);
    EXPECT_EQ(g.cellsAboveThreshold, c.cellsAboveThreshold);
    EXPECT_EQ(g.candidates.size(), c.candidates.size());
  }
}

// Re-searches of a resident cube keep the tree's plan, arenas and tables (issue 16): a second search and one
// at another threshold reuse them and still give the CPU tree's result; another grid, an exact search in
// between, or another cube make them again.
TEST(CudaTree, ReSearchKeepsTheWorkspaceAndStillGivesTheCpuTreesResult) {
  ST_REQUIRE_GPU(gpu);
  Problem p = standardProblem();
  p.cube.revision = search::nextCubeRevision();  // a resident cube
  NullProgress progress;
  CancelToken cancel;
  auto run = [&](const char* expect, const char* what) {
    const SearchResult g = gpu->search(p.cube, p.grid, p.params, progress, cancel);
    EXPECT_NE(gpu->lastNote().find(expect), std::string::npos) << what << ": " << gpu->lastNote();
    expectSameAsCpuTree(g, p);
  };
  run("made, kept for the next", "first search");
  run("kept from the last search", "re-search");
  EXPECT_NE(gpu->lastNote().find("tree plan kept"), std::string::npos) << gpu->lastNote();
  p.params.snrThreshold = 5.5;
  run("kept from the last search", "another threshold");
  p.grid = VelocityGrid{{3.0, 1.0}, 0.4, 31, 29};
  run("made, kept for the next", "another grid");
  SearchParams exact = p.params;
  exact.method = st::search::SearchMethod::Exact;
  gpu->search(p.cube, p.grid, exact, progress, cancel);
  run("made, kept for the next", "after an exact search");
  p.cube = makeCube(96, 70, 64, 12);
  p.cube.revision = search::nextCubeRevision();
  run("made, kept for the next", "another cube");
  run("kept from the last search", "its re-search");
  // A cube that is not kept on the device keeps nothing.
  p.cube.revision = 0;
  run("(made)", "cube without a revision");
}

TEST(CudaTree, CancelledAndBadMethod) {
  ST_REQUIRE_GPU(gpu);
  Problem p = standardProblem();
  NullProgress progress;
  CancelToken cancel;
  cancel.cancel();
  EXPECT_THROW(gpu->search(p.cube, p.grid, p.params, progress, cancel), Cancelled);
  CancelToken fresh;
  p.params.method = "fast";
  EXPECT_THROW(gpu->search(p.cube, p.grid, p.params, progress, fresh), InputError);
  // The method choice (method_choice.hpp) and the backend factory route tree requests by this answer.
  EXPECT_TRUE(gpu->supportsMethod("tree"));
  EXPECT_TRUE(gpu->supportsMethod("exact"));
  EXPECT_FALSE(gpu->supportsMethod("fast"));
}

}  // namespace
}  // namespace st

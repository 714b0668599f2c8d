// Out-of-core search (issue 20): tiles with the shift overlap give exactly the in-memory candidates, cells
// above threshold and velocity map, for the exact and the tree method, in strips and in 2-D tiles; the tree
// search's tile buffers do not grow with the thread count; memory sizes parse; raw frames' strips are read
// with the overlap the stages reach and are as tall as the budget allows.
#include <gtest/gtest.h>

#include <cstdlib>

#include "search_test_cubes.hpp"
#include "st/common/error.hpp"
#include "st/common/memory_budget.hpp"
#include "st/common/parallel.hpp"
#include "st/pipeline/memory_plan.hpp"
#include "st/pipeline/preprocess.hpp"
#include "st/pipeline/preprocess_out_of_core.hpp"
#include "st/search/cpu_backend.hpp"
#include "st/sim/simulator.hpp"
#include "st/search/tiled_search.hpp"
#include "st/search/tree_plan.hpp"
#include "st/search/tree_search.hpp"

namespace st {
namespace {

search::FilteredCube testCube() {
  const auto times = test::unevenTimes(24, 1.0, 3);
  FrameCube c = test::noiseCube(96, 80, times, 1.0, 11);
  const psf::Moffat psf = psf::Moffat::fromFwhm(2.5, 4.0);
  // Objects near tile borders, at the image's edges and moving out of the frame.
  test::injectMoffat(c, psf, 14.0, 40.0, 27.5, {0.6, -0.4});
  test::injectMoffat(c, psf, 12.0, 3.0, 60.0, {-0.5, 0.3});
  test::injectMoffat(c, psf, 16.0, 70.0, 41.0, {0.2, 0.7});
  test::injectMoffat(c, psf, 12.0, 90.0, 5.0, {0.9, 0.1});
  test::matchedFilter(c, psf, 3);
  search::FilteredCube fc;
  fc.frames = std::move(c);
  fc.sigmaF = 1.6;
  fc.psfFwhmPx = 2.5;
  return fc;
}

search::FilteredCube crop(const search::FilteredCube& full, const search::TileRect& r) {
  search::FilteredCube t;
  t.sigmaF = full.sigmaF;
  t.psfFwhmPx = full.psfFwhmPx;
  t.skyRate = full.skyRate;
  t.frames = FrameCube(r.width, r.height, full.frames.frameCount());
  t.frames.info() = full.frames.info();
  for (std::size_t n = 0; n < full.frames.frameCount(); ++n)
    for (int y = 0; y < r.height; ++y)
      for (int x = 0; x < r.width; ++x)
        t.frames.frame(n)[static_cast<std::size_t>(y) * r.width + x] =
            full.frames.frame(n)[static_cast<std::size_t>(y + r.y0) * full.frames.width() + x + r.x0];
  return t;
}

void expectSame(const search::SearchResult& a, const search::SearchResult& b) {
  EXPECT_EQ(a.cellsAboveThreshold, b.cellsAboveThreshold);
  EXPECT_EQ(a.snrThreshold, b.snrThreshold);
  ASSERT_EQ(a.candidates.size(), b.candidates.size());
  for (std::size_t i = 0; i < a.candidates.size(); ++i) {
    const auto& p = a.candidates[i];
    const auto& q = b.candidates[i];
    EXPECT_EQ(p.x, q.x) << i;
    EXPECT_EQ(p.y, q.y) << i;
    EXPECT_EQ(p.ivx, q.ivx) << i;
    EXPECT_EQ(p.ivy, q.ivy) << i;
    EXPECT_EQ(p.snr, q.snr) << i;
    EXPECT_EQ(p.nIn, q.nIn) << i;
    EXPECT_EQ(p.clusterCells, q.clusterCells) << i;
  }
  EXPECT_EQ(a.map.maxSnr, b.map.maxSnr);
  EXPECT_EQ(a.map.argX, b.map.argX);
  EXPECT_EQ(a.map.argY, b.map.argY);
}

class OutOfCore : public ::testing::TestWithParam<std::string> {};

TEST_P(OutOfCore, TilesGiveTheInMemoryResult) {
  const search::FilteredCube fc = testCube();
  const search::VelocityGrid grid{{0.0, 0.0}, 0.1, 21, 21};
  search::SearchParams params;
  params.method = GetParam();
  params.snrThreshold = 5.0;
  NullProgress progress;
  CancelToken cancel;
  auto backend = search::makeCpuBackend();
  const search::SearchResult whole = backend->search(fc, grid, params, progress, cancel);
  ASSERT_GE(whole.candidates.size(), 4u);
  const int overlap = search::searchOverlapPx(grid, fc.frames.timeOffsetsS());
  EXPECT_GE(overlap, 13);  // 1 px/s x ~13.5 s from t_ref at the ends
  const search::TileLoader load = [&](const search::TileRect& r) { return crop(fc, r); };
  // Strips of whole rows, then 2-D tiles.
  for (const std::size_t maxPixels : {std::size_t{96} * 50, std::size_t{45} * 45}) {
    const auto tiles = search::planSearchTiles(96, 80, overlap, maxPixels);
    ASSERT_GE(tiles.size(), 2u) << maxPixels;
    std::size_t owned = 0;
    for (const auto& t : tiles) {
      EXPECT_LE(t.read.pixels(), maxPixels);
      owned += t.owned.pixels();
    }
    EXPECT_EQ(owned, std::size_t{96} * 80);
    const search::SearchResult tiled = search::searchTiled(load, tiles, 96, 80, grid, params, progress, cancel);
    SCOPED_TRACE(std::to_string(tiles.size()) + " tiles");
    expectSame(whole, tiled);
  }
  // Overlap too small: the cells near the borders differ (the test can fail).
  const auto tiles = search::planSearchTiles(96, 80, 1, std::size_t{96} * 30);
  const search::SearchResult bad = search::searchTiled(load, tiles, 96, 80, grid, params, progress, cancel);
  EXPECT_NE(bad.cellsAboveThreshold + static_cast<std::int64_t>(bad.candidates.size()) * 1000,
            whole.cellsAboveThreshold + static_cast<std::int64_t>(whole.candidates.size()) * 1000);
}

INSTANTIATE_TEST_SUITE_P(Methods, OutOfCore, ::testing::Values("exact", "tree"));

// A small budget's tree buffers split a large grid into velocity blocks chosen by their additions (issue 20:
// 1-row tiles of one tree cost 1.44x the in-memory CPU time): the blocks run the whole tree's plan cut to
// their velocities, so the tiles give the in-memory result bit for bit. Before, each block ran its own plan
// and the values differed.
TEST(OutOfCoreTree, VelocityBlocksGiveTheInMemoryResult) {
  const auto times = test::unevenTimes(64, 0.4, 3);
  FrameCube c = test::noiseCube(128, 128, times, 1.0, 5);
  const double span = c.timeSpanS();
  const psf::Moffat psf = psf::Moffat::fromFwhm(2.5, 4.0);
  test::injectMoffat(c, psf, 8.0, 70.0, 50.0, {37.4 / span, -21.8 / span});
  test::injectMoffat(c, psf, 8.0, 20.0, 66.0, {-12.0 / span, 40.3 / span});
  test::matchedFilter(c, psf, 3);
  search::FilteredCube fc;
  fc.frames = std::move(c);
  fc.sigmaF = 1.6;
  fc.psfFwhmPx = 2.5;
  const search::VelocityGrid grid{{0.0, 0.0}, 1.0 / span, 121, 121};
  const search::TreePlan plan = search::buildTreePlan(fc.frames.timeOffsetsS(), grid);
  search::SearchParams params;
  params.method = search::SearchMethod::Tree;
  // In memory: buffers in which one tree over the whole grid is the cheapest plan (the default ones would
  // split this 128 px image's grid too, in 4 blocks of 64-row tiles).
  for (const std::size_t mb : {160, 120, 200, 80, 240}) {
    const std::size_t b = (mb << 20) * workerCount();
    const std::size_t perThread = search::treeTileBudgetPerThread(workerCount(), b);
    if (search::treeVelocityBlocks(plan, 128, 128, search::treeBlockSplitBytes(b), perThread).count() == 1) {
      params.bufferBytes = b;
      break;
    }
  }
  ASSERT_GT(params.bufferBytes, 0u) << "no buffer size tried gives one tree";
  NullProgress progress;
  CancelToken cancel;
  const search::SearchResult whole = search::makeCpuBackend()->search(fc, grid, params, progress, cancel);
  ASSERT_GE(whole.candidates.size(), 2u);
  params.bufferBytes = 1;  // the smallest buffers: one tree's 1-row tile (~43 MB) does not fit
  ASSERT_GT(search::treeTileBytes(plan, 128, 1), search::treeBlockSplitBytes(params.bufferBytes));
  const int overlap = search::searchOverlapPx(grid, fc.frames.timeOffsetsS());
  const auto tiles = search::planSearchTiles(128, 128, overlap, std::size_t{128} * (32 + 2 * overlap));
  ASSERT_GE(tiles.size(), 2u);
  const search::TileLoader load = [&](const search::TileRect& r) { return crop(fc, r); };
  const search::SearchResult tiled = search::searchTiled(load, tiles, 128, 128, grid, params, progress, cancel);
  expectSame(whole, tiled);
}

TEST(OutOfCorePlan, NoTileWhenNotEvenASmallOneFits) {
  EXPECT_TRUE(search::planSearchTiles(1000, 1000, 50, 100 * 100).empty());
  EXPECT_EQ(search::planSearchTiles(100, 100, 50, 100 * 100).size(), 1u);
}

TEST(OutOfCorePlan, TreeBuffersAreSharedByTheThreads) {
  EXPECT_EQ(search::treeTileBudgetPerThread(1), search::kTreeTileBudgetBytes);
  EXPECT_EQ(search::treeTileBudgetPerThread(2), search::kTreeTileBudgetBytes);
  EXPECT_EQ(search::treeTileBudgetPerThread(16) * 16, search::kTreeBuffersBytes);
  EXPECT_EQ(search::treeTileBudgetPerThread(64), search::kTreeMinTileBudgetBytes);
  EXPECT_EQ(search::treeTileBudgetPerThread(4, std::size_t{64} << 20), search::kTreeMinTileBudgetBytes);
}

// Without --fit the matched filter runs in place (one cube less): the same filtered frames and sigma_F as
// the copy.
TEST(OutOfCorePlan, InPlaceFilterGivesTheCopysFrames) {
  NullProgress p;
  CancelToken c;
  const sim::SimResult sim = sim::simulate(sim::preset("small"), 7, p, c);
  pipeline::PreprocessParams params;
  params.masters = sim::exactMasters(sim);
  const pipeline::Prepared copy = pipeline::preprocess(sim.cube, params, p, c);
  params.keepZeroBiased = false;
  const pipeline::Prepared inPlace = pipeline::preprocess(sim.cube, params, p, c);
  EXPECT_TRUE(inPlace.frames.empty());
  EXPECT_FALSE(copy.frames.empty());
  EXPECT_EQ(inPlace.filtered.sigmaF, copy.filtered.sigmaF);
  EXPECT_TRUE(inPlace.filtered.frames.mask().empty());
  EXPECT_EQ(inPlace.filtered.frames.width(), copy.filtered.frames.width());
  EXPECT_TRUE(inPlace.filtered.frames.pixels() == copy.filtered.frames.pixels());
  EXPECT_EQ(inPlace.filtered.frames.timeOffsetsS(), copy.filtered.frames.timeOffsetsS());
}

// Raw frames out of core (pipeline/preprocess_out_of_core): the overlap is what the stages reach (half a
// 64 px mesh cell, the static sources' 32 px stack mesh, the filter's radius), not two mesh cells; the
// strips are as tall as the budget allows, so that the overlap is a small part of the rows read.
TEST(OutOfCorePreprocessPlan, OverlapIsTheStagesReach) {
  pipeline::PreprocessParams params;
  const pipeline::PreprocessHalo h = pipeline::preprocessHalo(params);
  EXPECT_EQ(h.meshes, 32);
  EXPECT_EQ(h.staticSources, 32);
  EXPECT_GE(h.filter, 10);  // a Moffat of twice the assumed 3 px FWHM, truncated at 1e-3 of its peak
  EXPECT_LE(h.filter, 32);
  EXPECT_EQ(h.overlap(), 32);
  EXPECT_EQ(pipeline::preprocessOverlapPx(params), 32);
  EXPECT_NE(h.describe().find("meshes 32"), std::string::npos) << h.describe();
  params.frameBackground.meshPx = 128;  // a coarser SEP mesh reaches further
  EXPECT_EQ(pipeline::preprocessOverlapPx(params), 64);
  params.psfFwhmPx = 20.0;  // a wide PSF: the filter's radius
  EXPECT_GT(pipeline::preprocessOverlapPx(params), 64);
}

TEST(OutOfCorePreprocessPlan, StripsAreAsTallAsTheBudgetAllows) {
  const pipeline::CubeShape shape{256, 1024, 100};
  const int overlap = 32;
  // The estimate of the whole frame read at once, and of a quarter of it with its overlap.
  const double whole = pipeline::estimatePreprocessPeak(shape, false, 2).total();
  const double quarter = pipeline::estimatePreprocessPeak({256, 256 + 2 * overlap, 100}, false, 2).total();
  const auto plan = pipeline::planOutOfCorePreprocess(shape, static_cast<std::size_t>(quarter * 1.05), 2, overlap);
  ASSERT_EQ(plan.strips.size(), 4u);
  int owned = 0, read = 0, next = 0;
  for (const auto& s : plan.strips) {
    EXPECT_EQ(s.ownY0, next);  // the strips tile the rows
    next = s.ownY0 + s.ownRows;
    owned += s.ownRows;
    read += s.read.height;
    EXPECT_LE(s.read.y0, std::max(0, s.ownY0 - overlap));
    EXPECT_GE(s.read.y0 + s.read.height, std::min(1024, s.ownY0 + s.ownRows + overlap));
  }
  EXPECT_EQ(owned, 1024);
  EXPECT_EQ(read, 1024 + 6 * overlap);  // 1.19x the rows
  EXPECT_LE(plan.perStrip.total(), quarter * 1.05);
  EXPECT_EQ(plan.reference, 2u);
  // More room, fewer strips; the whole frame's room, one strip without overlap.
  const double half = pipeline::estimatePreprocessPeak({256, 512 + overlap, 100}, false, 2).total();
  EXPECT_EQ(pipeline::planOutOfCorePreprocess(shape, static_cast<std::size_t>(half * 1.01), 2, overlap).strips.size(),
            2u);
  const auto one = pipeline::planOutOfCorePreprocess(shape, static_cast<std::size_t>(whole), 2, overlap);
  ASSERT_EQ(one.strips.size(), 1u);
  EXPECT_EQ(one.strips[0].read.height, 1024);
  // Not even the smallest strip (64 rows and the overlaps): none, with the need.
  const auto none = pipeline::planOutOfCorePreprocess(shape, 1 << 20, 2, overlap);
  EXPECT_TRUE(none.strips.empty());
  EXPECT_GT(none.smallestStrip.total(), double(1 << 20));
}

TEST(MemoryBudget, ParsesSizes) {
  EXPECT_EQ(parseMemorySize("8G"), std::size_t{8} << 30);
  EXPECT_EQ(parseMemorySize("500M"), std::size_t{500} << 20);
  EXPECT_EQ(parseMemorySize("1.5GiB"), std::size_t{3} << 29);
  EXPECT_EQ(parseMemorySize("2048k"), std::size_t{2} << 20);
  EXPECT_EQ(parseMemorySize("12345"), 12345u);
  EXPECT_THROW(parseMemorySize("lots"), InputError);
  EXPECT_THROW(parseMemorySize("-1G"), InputError);
  EXPECT_THROW(parseMemorySize("8X"), InputError);
  EXPECT_GE(defaultMemoryBudget(), std::size_t{64} << 20);
  EXPECT_GT(peakResidentBytes(), 0u);
}

}  // namespace
}  // namespace st

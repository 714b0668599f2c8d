// The tree (hierarchical) search against the exact search: implied per-frame shifts within +-1 px of
// round(v dt) at every frame and velocity; the tree's statistic equals a brute-force sum along its implied
// shifts; SNR loss on injected objects; nothing the exact search finds at SNR >= threshold + 1 is lost.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <tuple>

#include "search_test_cubes.hpp"
#include "st/common/error.hpp"
#include "st/common/parallel.hpp"
#include "st/search/cpu_backend.hpp"
#include "st/search/ipsa.hpp"
#include "st/search/method_choice.hpp"
#include "st/search/tree_plan.hpp"
#include "st/search/tree_search.hpp"

namespace st::search {
namespace {

std::vector<double> offsetsOf(const std::vector<double>& times) {
  double mean = 0.0;
  for (double t : times)
    mean += t;
  mean /= static_cast<double>(times.size());
  std::vector<double> dt;
  for (double t : times)
    dt.push_back(t - mean);
  return dt;
}

// Every grid velocity, every frame: |tree shift - round(v dt)| <= 1 px on both axes.
int worstDeviation(const std::vector<double>& dt, const VelocityGrid& grid) {
  const TreePlan plan = buildTreePlan(dt, grid);
  int worst = 0;
  for (int iy = 0; iy < grid.nvy; ++iy) {
    for (int ix = 0; ix < grid.nvx; ++ix) {
      const Velocity v = grid.at(ix, iy);
      const auto s = treeImpliedShifts(plan, ix, iy);
      for (std::size_t n = 0; n < dt.size(); ++n) {
        worst = std::max(worst, std::abs(s[n].first - ipsaShift(v.vx, dt[n])));
        worst = std::max(worst, std::abs(s[n].second - ipsaShift(v.vy, dt[n])));
      }
    }
  }
  EXPECT_EQ(worst, std::max(plan.maxAbsErrX, plan.maxAbsErrY));
  return worst;
}

TEST(SearchTree, ImpliedShiftsWithinOnePixelUnevenTimes) {
  for (unsigned seed : {1u, 2u, 3u}) {
    const std::vector<double> dt = offsetsOf(test::unevenTimes(97, 0.37, seed, seed == 2));
    const double span = *std::max_element(dt.begin(), dt.end()) - *std::min_element(dt.begin(), dt.end());
    const VelocityGrid grid{{0.7 / span * 13.0, -3.1}, 1.0 / span, 41, 33};
    EXPECT_LE(worstDeviation(dt, grid), 1) << "seed " << seed;
  }
}

TEST(SearchTree, ImpliedShiftsWithinOnePixelPaperCadence) {
  // The paper's problem: 1500 frames at 16.7 Hz, 100 x 100 velocities 1 px / span apart (here every 4th
  // column of velocities is checked on x and all on y to keep the test fast: the axes are independent).
  std::vector<double> t(1500);
  for (std::size_t n = 0; n < t.size(); ++n)
    t[n] = static_cast<double>(n) / 16.7;
  const std::vector<double> dt = offsetsOf(t);
  const double span = dt.back() - dt.front();
  const VelocityGrid grid{{0.0, 0.0}, 1.0 / span, 100, 100};
  const TreePlan plan = buildTreePlan(dt, grid);
  EXPECT_LE(plan.maxAbsErrX, 1);
  EXPECT_LE(plan.maxAbsErrY, 1);
  std::size_t off = 0, all = 0;
  for (int i = 0; i < 100; i += 3) {
    const auto s = treeImpliedShifts(plan, i, 99 - i);
    for (std::size_t n = 0; n < dt.size(); ++n) {
      off += (s[n].first != ipsaShift(grid.at(i, 0).vx, dt[n])) +
             (s[n].second != ipsaShift(grid.at(0, 99 - i).vy, dt[n]));
      all += 2;
      ASSERT_LE(std::abs(s[n].first - ipsaShift(grid.at(i, 0).vx, dt[n])), 1);
      ASSERT_LE(std::abs(s[n].second - ipsaShift(grid.at(0, 99 - i).vy, dt[n])), 1);
    }
  }
  std::printf(
      "paper cadence: %.1f%% of sampled (velocity, frame, axis) shifts differ (by 1 px) from round(v dt)\n",
      100.0 * static_cast<double>(off) / static_cast<double>(all));
  // Distinguishable velocities grow with the span: per axis 2 ceil(halfRange / step - 1/2) + 1 velocities,
  // step = max(grid step, kTreeStepPx / node span); so the 2-D count goes with the span squared.
  const double halfRange = 49.5 * grid.stepPxS;
  for (std::size_t i = 1; i < plan.nodes.size(); ++i) {
    const TreeNode& n = plan.nodes[i];
    if (n.leaf()) continue;
    const double step = std::max(grid.stepPxS, kTreeStepPx / n.spanS);
    const std::size_t k = static_cast<std::size_t>(std::max(0.0, std::ceil(halfRange / step - 0.5 - 1e-9)));
    ASSERT_EQ(n.x.v.size(), 2 * k + 1) << "node " << i;
    ASSERT_EQ(n.y.v.size(), 2 * k + 1) << "node " << i;
  }
  const TreeNode& grandchild =
      plan.nodes[static_cast<std::size_t>(plan.nodes[static_cast<std::size_t>(plan.nodes[0].left)].left)];
  EXPECT_LE(grandchild.velocities(), 53u * 53u);
}

struct Injected {
  double x, y;
  Velocity v;
};

FilteredCube injectedCube(const std::vector<Injected>& objects, const psf::Moffat& psf, int r, double snr,
                          int w, int h, std::size_t frames, unsigned seed, VelocityGrid& grid) {
  FilteredCube fc;
  fc.frames = test::noiseCube(w, h, test::unevenTimes(frames, 0.4, seed), 1.0, seed + 7);
  const double p2 = test::sumP2(psf, r);
  const double alpha = snr / (std::sqrt(static_cast<double>(frames)) * std::sqrt(p2));
  grid.stepPxS = 1.0 / fc.frames.timeSpanS();
  for (const Injected& o : objects)
    test::injectMoffat(fc.frames, psf, alpha, o.x, o.y, o.v);
  test::matchedFilter(fc.frames, psf, r);
  fc.sigmaF = std::sqrt(p2);
  fc.psfFwhmPx = psf.fwhm();
  return fc;
}

const Candidate* nearest(const SearchResult& r, double x, double y, int radius) {
  return test::nearestFound(r, x, y, radius);
}

TEST(SearchTree, MatchesExactOnInjectedObjects) {
  const psf::Moffat psf{psf::Moffat::radiusForFwhm(3.0, 4.0), 4.0};
  const int r = 5;
  std::vector<double> losses;
  NullProgress progress;
  CancelToken cancel;
  auto backend = makeCpuBackend();
  for (unsigned cubeSeed = 0; cubeSeed < 3; ++cubeSeed) {
    // 96 x 96 px, 64 uneven frames; grid 31 x 31 (+-15 px over the span), 9 objects at random
    // (off-grid) velocities on a 3 x 3 lattice of positions, two of them near the edges.
    std::mt19937_64 rng(100 + cubeSeed);
    std::uniform_real_distribution<double> uv(-14.0, 14.0);
    VelocityGrid grid{{0.0, 0.0}, 0.0, 31, 31};
    std::vector<Injected> objects;
    for (int i = 0; i < 9; ++i)
      objects.push_back({6.0 + 42.0 * (i % 3), 6.0 + 42.0 * (i / 3), {uv(rng), uv(rng)}});
    // Velocities are in px over the span until the cube (and so the span) exists: rescale after.
    FilteredCube fc = [&] {
      FilteredCube probe;
      probe.frames = test::noiseCube(8, 8, test::unevenTimes(64, 0.4, cubeSeed + 1), 1.0, 1);
      const double span = probe.frames.timeSpanS();
      for (auto& o : objects)
        o.v = {o.v.vx / span, o.v.vy / span};
      return injectedCube(objects, psf, r, 14.0, 96, 96, 64, cubeSeed + 1, grid);
    }();
    SearchParams params;  // SNR 7
    const SearchResult exact = backend->search(fc, grid, params, progress, cancel);
    params.method = st::search::SearchMethod::Tree;
    const SearchResult tree = backend->search(fc, grid, params, progress, cancel);
    EXPECT_EQ(tree.method, st::search::SearchMethod::Tree);
    EXPECT_EQ(exact.method, st::search::SearchMethod::Exact);
    EXPECT_EQ(tree.trials.total(), exact.trials.total());
    for (const Injected& o : objects) {
      const Candidate* e = nearest(exact, o.x, o.y, 3);
      const Candidate* t = nearest(tree, o.x, o.y, 3);
      ASSERT_NE(e, nullptr);
      ASSERT_NE(t, nullptr) << "object at " << o.x << "," << o.y << " lost by the tree search";
      losses.push_back(1.0 - t->snr / e->snr);
      // The SNR surface is flat over a few grid steps near the peak (1 step moves the ends by 1/2 px), so
      // the best cell of the cluster may move by a few steps; the position may not.
      EXPECT_LE(std::abs(t->ivx - e->ivx), 4);
      EXPECT_LE(std::abs(t->ivy - e->ivy), 4);
      EXPECT_LE(std::abs(t->x - e->x), 1);
      EXPECT_LE(std::abs(t->y - e->y), 1);
    }
    // Nothing the exact search finds at SNR >= threshold + 1 is lost.
    for (const Candidate& e : exact.candidates) {
      if (e.snr < exact.snrThreshold + 1.0) continue;
      EXPECT_NE(nearest(tree, e.x, e.y, 6), nullptr) << "exact candidate at " << e.x << "," << e.y;
    }
  }
  std::sort(losses.begin(), losses.end());
  const double median = losses[losses.size() / 2];
  std::printf("tree vs exact SNR loss over %zu objects: min %.4f median %.4f max %.4f\n", losses.size(),
              losses.front(), median, losses.back());
  EXPECT_LE(median, 0.03) << "median SNR loss";
  EXPECT_LE(losses.back(), 0.10) << "worst SNR loss";
}

/// The brute-force sum of F_n(x + sx_n, y + sy_n) over the frames (samples outside the frame contribute 0).
double sumAlongShifts(const FrameCube& frames, int x, int y, const std::vector<std::pair<int, int>>& s) {
  const int w = frames.width(), h = frames.height();
  double sum = 0.0;
  for (std::size_t n = 0; n < frames.frameCount(); ++n) {
    const int xs = x + s[n].first, ys = y + s[n].second;
    if (xs < 0 || ys < 0 || xs >= w || ys >= h) continue;
    sum += frames.frame(n)[static_cast<std::size_t>(ys) * w + xs];
  }
  return sum;
}

// Every velocity's map maximum: S there equals the brute-force sum of F_n(x + sx_n, y + sy_n) along the
// tree's implied shifts (samples outside the frame contribute 0), normalised with the exact N_in.
void expectSumsAlongImpliedShifts(int w, int h, std::size_t frames, const VelocityGrid& gridInSpanUnits,
                                  unsigned seed) {
  FilteredCube fc;
  fc.frames = test::noiseCube(w, h, test::unevenTimes(frames, 0.5, seed, true), 1.0, seed);
  fc.sigmaF = 1.0;
  fc.psfFwhmPx = 2.0;
  const double span = fc.frames.timeSpanS();
  VelocityGrid grid = gridInSpanUnits;
  grid.centre = {grid.centre.vx / span, grid.centre.vy / span};
  grid.stepPxS /= span;
  SearchParams params;
  params.method = st::search::SearchMethod::Tree;
  params.minFrameFraction = 0.3;
  NullProgress progress;
  CancelToken cancel;
  const SearchResult r = makeCpuBackend()->search(fc, grid, params, progress, cancel);
  const TreePlan plan = buildTreePlan(fc.frames.timeOffsetsS(), grid);
  const std::vector<double> dt = fc.frames.timeOffsetsS();
  for (int iy = 0; iy < grid.nvy; ++iy) {
    for (int ix = 0; ix < grid.nvx; ++ix) {
      const std::size_t iv = static_cast<std::size_t>(iy) * grid.nvx + ix;
      const int x = r.map.argX[iv];
      const int y = r.map.argY[iv];
      if (x < 0) continue;  // no cell with enough frames
      const double sum = sumAlongShifts(fc.frames, x, y, treeImpliedShifts(plan, ix, iy));
      const IpsaCell exact = ipsaReference(fc.frames, dt, x, y, grid.at(ix, iy));
      ASSERT_NEAR(r.map.maxSnr[iv], sum / std::sqrt(double(exact.nIn)), 2e-4) << ix << "," << iy;
    }
  }
}

TEST(SearchTree, StatisticIsTheSumAlongItsImpliedShifts) {
  // Small: 37 shuffled uneven frames, grid off-centre. Large: 160 frames, a grid of +-30 px over the span on
  // a 40 px image (many samples out of frame, deep tree, wide margins).
  expectSumsAlongImpliedShifts(41, 35, 37, VelocityGrid{{4.0, -2.0}, 1.0, 25, 19}, 5);
  expectSumsAlongImpliedShifts(40, 40, 160, VelocityGrid{{3.0, 0.0}, 1.0, 61, 45}, 6);
}

TEST(SearchTree, NoisePeaksAboveThresholdPlusOneMostlyKept) {
  // Matched-filtered noise at a low threshold (2.5), so the exact search reports many noise peaks.
  const psf::Moffat psf{psf::Moffat::radiusForFwhm(3.0, 4.0), 4.0};
  FilteredCube fc;
  fc.frames = test::noiseCube(64, 64, test::unevenTimes(48, 0.3, 21), 1.0, 21);
  test::matchedFilter(fc.frames, psf, 5);
  fc.sigmaF = std::sqrt(test::sumP2(psf, 5));
  fc.psfFwhmPx = psf.fwhm();
  const double span = fc.frames.timeSpanS();
  const VelocityGrid grid{{1.0 / span, 0.0}, 1.0 / span, 21, 21};
  SearchParams params;
  params.snrThreshold = 2.5;
  params.maxCandidates = 1000000;
  NullProgress progress;
  CancelToken cancel;
  auto backend = makeCpuBackend();
  const SearchResult exact = backend->search(fc, grid, params, progress, cancel);
  params.method = st::search::SearchMethod::Tree;
  const SearchResult tree = backend->search(fc, grid, params, progress, cancel);
  // Noise peaks are not objects: the tree samples up to ~1/4 of the frames 1 px off the exact track, which
  // decorrelates a peak made of noise, so a few may drop below threshold (objects do not: see
  // MatchesExactOnInjectedObjects). At most a third of them may go.
  int checked = 0, lost = 0;
  for (const Candidate& e : exact.candidates) {
    if (e.snr < exact.snrThreshold + 1.0) continue;
    ++checked;
    lost += nearest(tree, e.x, e.y, 4) == nullptr;
  }
  EXPECT_GE(checked, 5);
  EXPECT_LE(3 * lost, checked);
  // The velocity maps (max over pixels of noise) agree in the median; single velocities may differ more
  // (the tree may sample many frames 1 px off the exact track, which decorrelates noise peaks).
  std::vector<double> diffs;
  for (std::size_t i = 0; i < grid.count(); ++i)
    diffs.push_back(std::abs(tree.map.maxSnr[i] / exact.map.maxSnr[i] - 1.0));
  std::sort(diffs.begin(), diffs.end());
  std::printf(
      "noise: %d exact candidates >= threshold + 1, %d without a tree candidate; map difference median "
      "%.3f, worst %.3f\n",
      checked, lost, diffs[diffs.size() / 2], diffs.back());
  EXPECT_LE(diffs[diffs.size() / 2], 0.05);
}

// Velocity blocks (tree_search.hpp, issue 20): the blocks tile the grid, each block's cell j is the grid's cell
// i0 + j, and a grid too large for one tree's 1-row tile is searched block by block with every velocity's
// map maximum equal to the brute-force sum along its block's implied shifts, the object found at its place
// and velocity (indices of the whole grid).
TEST(SearchTree, VelocityBlocksTileTheGrid) {
  const VelocityGrid grid{{0.3, -0.2}, 0.013, 23, 17};
  const TreeBlocks b{3, 2, 8, 9};
  std::vector<int> seen(grid.count(), 0);
  for (int by = 0; by < b.blocksY; ++by) {
    for (int bx = 0; bx < b.blocksX; ++bx) {
      int ix0 = 0, iy0 = 0;
      const VelocityGrid sub = treeBlockGrid(grid, b, bx, by, ix0, iy0);
      EXPECT_EQ(sub.stepPxS, grid.stepPxS);
      for (int jy = 0; jy < sub.nvy; ++jy) {
        for (int jx = 0; jx < sub.nvx; ++jx) {
          ++seen[static_cast<std::size_t>(iy0 + jy) * grid.nvx + ix0 + jx];
          EXPECT_NEAR(sub.at(jx, jy).vx, grid.at(ix0 + jx, iy0 + jy).vx, 1e-12);
          EXPECT_NEAR(sub.at(jx, jy).vy, grid.at(ix0 + jx, iy0 + jy).vy, 1e-12);
        }
      }
    }
  }
  EXPECT_EQ(std::count(seen.begin(), seen.end(), 1), static_cast<std::ptrdiff_t>(grid.count()));
}

// A block's plan is the whole tree's cut to its velocities (treeSubPlan): the same implied shifts at every
// velocity, on uneven registered frames, and no more stacks at any node than the whole tree's.
TEST(SearchTree, BlockPlanIsTheWholeTreesCut) {
  const std::vector<double> dt = offsetsOf(test::unevenTimes(53, 0.6, 4, true));
  std::vector<PixelOffset> offsets;
  for (std::size_t n = 0; n < dt.size(); ++n)
    offsets.push_back({0.37 * std::sin(0.3 * static_cast<double>(n)), -0.21 * std::cos(0.2 * static_cast<double>(n))});
  const double span = *std::max_element(dt.begin(), dt.end()) - *std::min_element(dt.begin(), dt.end());
  const VelocityGrid grid{{2.0 / span, -1.0 / span}, 1.0 / span, 37, 29};
  const TreePlan whole = buildTreePlan(dt, grid, offsets);
  for (const auto& [ix0, nx, iy0, ny] : {std::tuple{0, 37, 0, 29}, std::tuple{0, 10, 0, 8},
                                          std::tuple{27, 10, 21, 8}, std::tuple{13, 7, 9, 11}, std::tuple{36, 1, 5, 1}}) {
    const TreePlan sub = treeSubPlan(whole, ix0, nx, iy0, ny);
    ASSERT_EQ(sub.nodes.size(), whole.nodes.size());
    EXPECT_EQ(sub.nodes[0].x.v.size(), static_cast<std::size_t>(nx));
    EXPECT_EQ(sub.nodes[0].y.v.size(), static_cast<std::size_t>(ny));
    for (std::size_t i = 0; i < sub.nodes.size(); ++i) {
      EXPECT_LE(sub.nodes[i].velocities(), whole.nodes[i].velocities()) << "node " << i;
      EXPECT_EQ(sub.nodes[i].direct(), whole.nodes[i].direct()) << "node " << i;
    }
    for (int jy = 0; jy < ny; ++jy)
      for (int jx = 0; jx < nx; ++jx)
        ASSERT_EQ(treeImpliedShifts(sub, jx, jy), treeImpliedShifts(whole, ix0 + jx, iy0 + jy)) << jx << "," << jy;
    if (nx * ny < 37 * 29) {
      EXPECT_LT(treeAdditions(sub, 64, 64, 8), treeAdditions(whole, 64, 64, 8));
      EXPECT_LT(treeTileBytes(sub, 64, 1), treeTileBytes(whole, 64, 1));
    }
  }
  EXPECT_THROW(treeSubPlan(whole, 30, 8, 0, 1), InputError);
  EXPECT_THROW(treeSubPlan(whole, 0, 0, 0, 1), InputError);
}

// The shared plan (issue 16: the estimate and the search of a cube build it once): the same object for the
// same times, grid and offsets (none and all-zero alike), buildTreePlan's plan, and a new one when any of
// them changes; offsets of the wrong count still throw.
TEST(SearchTree, SharedPlanIsBuiltOncePerTimesGridAndOffsets) {
  const std::vector<double> dt = offsetsOf(test::unevenTimes(41, 0.5, 3, true));
  const double span = *std::max_element(dt.begin(), dt.end()) - *std::min_element(dt.begin(), dt.end());
  const VelocityGrid grid{{1.0 / span, 0.5 / span}, 1.0 / span, 21, 17};
  const auto a = sharedTreePlan(dt, grid);
  EXPECT_EQ(sharedTreePlan(dt, grid).get(), a.get());
  EXPECT_EQ(sharedTreePlan(dt, grid, std::vector<PixelOffset>(dt.size())).get(), a.get());
  const TreePlan built = buildTreePlan(dt, grid);
  ASSERT_EQ(a->nodes.size(), built.nodes.size());
  for (int jy = 0; jy < grid.nvy; jy += 4)
    for (int jx = 0; jx < grid.nvx; jx += 4)
      ASSERT_EQ(treeImpliedShifts(*a, jx, jy), treeImpliedShifts(built, jx, jy));
  VelocityGrid wider = grid;
  wider.nvx += 2;
  const auto b = sharedTreePlan(dt, wider);
  EXPECT_NE(b.get(), a.get());
  // Two plans are kept (a registered cube's estimate asks without offsets, its search with them).
  EXPECT_EQ(sharedTreePlan(dt, grid).get(), a.get());
  EXPECT_EQ(sharedTreePlan(dt, wider).get(), b.get());
  EXPECT_EQ(b->nodes[0].x.v.size(), static_cast<std::size_t>(wider.nvx));
  std::vector<PixelOffset> offsets(dt.size());
  offsets[3] = {0.4, -0.2};
  const auto c = sharedTreePlan(dt, wider, offsets);
  EXPECT_NE(c.get(), b.get());
  EXPECT_DOUBLE_EQ(c->ox[std::find(c->frame.begin(), c->frame.end(), 3) - c->frame.begin()], 0.4);
  std::vector<double> later = dt;
  later.back() += 0.25;
  EXPECT_NE(sharedTreePlan(later, wider, offsets).get(), c.get());
  EXPECT_THROW(sharedTreePlan(dt, grid, std::vector<PixelOffset>(3)), InputError);
}

// The velocity blocks are chosen by their additions (issue 20): `bench memory --raw --frames 100 --size
// 256x1024` under --memory-limit 200M gave the search 50 MB of tree buffers, in which one tree's 1-row tile
// of the 111^2 grid fits, so the grid used to stay one tree in 1-row tiles (1.6e10 additions, 1.44x the
// in-memory CPU time) where blocks with taller tiles add less.
TEST(SearchTree, VelocityBlocksChosenByTheirAdditions) {
  std::vector<double> t(100);
  for (std::size_t n = 0; n < t.size(); ++n)
    t[n] = 0.6 * static_cast<double>(n);
  const std::vector<double> dt = offsetsOf(t);
  const double span = dt.back() - dt.front();
  const VelocityGrid grid{{0.0, 0.0}, 1.0 / span, 111, 111};
  const int width = 256, height = 1024;
  const std::size_t buffers = std::size_t{50} << 20;
  const TreePlan whole = buildTreePlan(dt, grid);
  const std::size_t perThread = treeTileBudgetPerThread(2, buffers);
  // What the grid-size rule ran: one tree (its 1-row tile fits the buffers), as many rows as fit a thread.
  ASSERT_LE(treeTileBytes(whole, width, 1), treeBlockSplitBytes(buffers)) << "the case no longer fits one tree";
  const int oneTreeRows = treeTileRows(whole, width, perThread);
  const double oneTree = treeAdditions(whole, width, height, oneTreeRows);
  const MethodEstimate e = estimateMethods(width, height, dt, grid, cpuCostModel(2), 2, buffers);
  std::printf("one tree: %d-row tiles, %.3g additions; chosen: %d blocks, %d-row tiles, %.3g additions, %.1f MB a "
              "thread\n",
              oneTreeRows, oneTree, e.treeBlocks, e.treeTileRows, e.treeAdditions, e.treeTileBytes / 1048576.0);
  EXPECT_GT(e.treeBlocks, 1);
  EXPECT_GT(e.treeTileRows, oneTreeRows);
  EXPECT_LT(e.treeAdditions, 0.9 * oneTree);
  EXPECT_LE(e.treeTileBytes, treeBlockSplitBytes(buffers));
  // The choice is the cheapest of the splits it prices: no fewer additions with 2 x 2 or 3 x 3 blocks.
  const TreeBlocks chosen = treeVelocityBlocks(whole, width, height, treeBlockSplitBytes(buffers), perThread);
  EXPECT_EQ(chosen.count(), e.treeBlocks);
  EXPECT_EQ(chosen.additions, e.treeAdditions);
  for (const int k : {2, 3}) {
    double sum = 0.0;
    const int n = (111 + k - 1) / k;
    for (int by = 0; by < k; ++by) {
      for (int bx = 0; bx < k; ++bx) {
        const int nx = std::min(n, 111 - bx * n), ny = std::min(n, 111 - by * n);
        const TreePlan sub = treeSubPlan(whole, bx * n, nx, by * n, ny);
        sum += treeAdditions(sub, width, height, treeTileRows(sub, width, perThread));
      }
    }
    EXPECT_LE(chosen.additions, 1.02 * sum) << k << " x " << k << " blocks";
  }
  // With the default buffers (in memory) one tree in tall tiles stays the cheapest.
  EXPECT_EQ(estimateMethods(width, height, dt, grid, cpuCostModel(2), 2).treeBlocks, 1);
}

TEST(SearchTree, LargeGridSearchedInVelocityBlocks) {
  // 128 x 128 px, 64 uneven frames, 121^2 velocities: one tree's 1-row tile needs ~33 MB, more than the
  // smallest split size (24 MB, bufferBytes 1 byte), so the grid is split.
  const psf::Moffat psf{psf::Moffat::radiusForFwhm(2.5, 4.0), 4.0};
  VelocityGrid grid{{0.0, 0.0}, 0.0, 121, 121};
  const Injected o{70.0, 50.0, {0.0, 0.0}};
  FilteredCube fc = injectedCube({}, psf, 4, 20.0, 128, 128, 64, 3, grid);
  const double span = fc.frames.timeSpanS();
  std::vector<Injected> objects{{o.x, o.y, {37.4 / span, -21.8 / span}}};
  fc = injectedCube(objects, psf, 4, 20.0, 128, 128, 64, 3, grid);
  const std::vector<double> dt = fc.frames.timeOffsetsS();
  const TreePlan whole = buildTreePlan(dt, grid);
  const TreeBlocks blocks =
      treeVelocityBlocks(whole, 128, 128, treeBlockSplitBytes(1), treeTileBudgetPerThread(workerCount(), 1));
  ASSERT_GT(blocks.count(), 1) << "the test's grid no longer needs blocks";
  // Buffers in which one tree over the whole grid is the cheapest plan, for the reference run.
  std::size_t oneTreeBuffers = 0;
  for (const std::size_t mb : {160, 120, 200, 80, 240}) {
    const std::size_t b = (mb << 20) * workerCount();
    if (treeVelocityBlocks(whole, 128, 128, treeBlockSplitBytes(b), treeTileBudgetPerThread(workerCount(), b))
            .count() == 1) {
      oneTreeBuffers = b;
      break;
    }
  }
  ASSERT_GT(oneTreeBuffers, 0u) << "no buffer size tried gives one tree";
  std::printf("%d x %d blocks of %d x %d velocities\n", blocks.blocksX, blocks.blocksY, blocks.blockNvx,
              blocks.blockNvy);
  SearchParams params;
  params.method = st::search::SearchMethod::Tree;
  params.bufferBytes = 1;
  NullProgress progress;
  CancelToken cancel;
  const SearchResult r = makeCpuBackend()->search(fc, grid, params, progress, cancel);
  ASSERT_EQ(r.map.maxSnr.size(), grid.count());
  std::size_t checked = 0;
  for (int by = 0; by < blocks.blocksY; ++by) {
    for (int bx = 0; bx < blocks.blocksX; ++bx) {
      int ix0 = 0, iy0 = 0;
      const VelocityGrid sub = treeBlockGrid(grid, blocks, bx, by, ix0, iy0);
      // A sample of each block's velocities (corners and a diagonal): the whole tree's sums.
      for (int j = 0; j < std::min(sub.nvx, sub.nvy); j += 7) {
        for (const auto& [jx, jy] : {std::pair{j, j}, std::pair{sub.nvx - 1 - j, j}}) {
          const std::size_t iv = static_cast<std::size_t>(iy0 + jy) * grid.nvx + ix0 + jx;
          const int x = r.map.argX[iv], y = r.map.argY[iv];
          if (x < 0) continue;
          const double sum = sumAlongShifts(fc.frames, x, y, treeImpliedShifts(whole, ix0 + jx, iy0 + jy));
          const IpsaCell exact = ipsaReference(fc.frames, dt, x, y, grid.at(ix0 + jx, iy0 + jy));
          ASSERT_NEAR(r.map.maxSnr[iv], sum / (fc.sigmaF * std::sqrt(double(exact.nIn))), 2e-4)
              << "velocity " << ix0 + jx << "," << iy0 + jy;
          ++checked;
        }
      }
    }
  }
  EXPECT_GT(checked, 4u * static_cast<std::size_t>(blocks.count()));
  const Candidate* c = nearest(r, o.x, o.y, 2);
  ASSERT_NE(c, nullptr) << "object lost";
  const Velocity v = objects.front().v;
  EXPECT_LE(std::abs(c->v.vx - v.vx), 2.0 * grid.stepPxS);
  EXPECT_LE(std::abs(c->v.vy - v.vy), 2.0 * grid.stepPxS);
  EXPECT_EQ(c->v.vx, grid.at(c->ivx, c->ivy).vx);  // indices of the whole grid
  EXPECT_GT(c->snr, 0.85 * 20.0);
  // One tree over the whole grid gives the same values, cells and candidates, bit for bit (the blocks of
  // each velocity's own plan, before 2026-11-27, did not: their shifts may differ by 1 px from the whole
  // tree's).
  params.bufferBytes = oneTreeBuffers;
  const SearchResult one = makeCpuBackend()->search(fc, grid, params, progress, cancel);
  EXPECT_EQ(r.map.maxSnr, one.map.maxSnr);
  EXPECT_EQ(r.map.argX, one.map.argX);
  EXPECT_EQ(r.map.argY, one.map.argY);
  EXPECT_EQ(r.cellsAboveThreshold, one.cellsAboveThreshold);
  ASSERT_EQ(r.candidates.size(), one.candidates.size());
  for (std::size_t i = 0; i < r.candidates.size(); ++i) {
    EXPECT_EQ(r.candidates[i].x, one.candidates[i].x) << i;
    EXPECT_EQ(r.candidates[i].y, one.candidates[i].y) << i;
    EXPECT_EQ(r.candidates[i].ivx, one.candidates[i].ivx) << i;
    EXPECT_EQ(r.candidates[i].ivy, one.candidates[i].ivy) << i;
    EXPECT_EQ(r.candidates[i].snr, one.candidates[i].snr) << i;
  }
}

TEST(SearchTree, RejectsUnknownMethodAndBadInput) {
  FilteredCube fc;
  fc.frames = test::noiseCube(16, 16, {0.0, 1.0, 2.0}, 1.0, 1);
  fc.sigmaF = 1.0;
  fc.psfFwhmPx = 2.0;
  SearchParams params;
  params.method = "fast";
  NullProgress progress;
  CancelToken cancel;
  const VelocityGrid grid{{0.0, 0.0}, 0.5, 3, 3};
  EXPECT_THROW(makeCpuBackend()->search(fc, grid, params, progress, cancel), InputError);
  EXPECT_THROW(buildTreePlan({1.0}, grid), InputError);
  EXPECT_THROW(buildTreePlan({1.0, 1.0}, grid), InputError);
  params.method = st::search::SearchMethod::Tree;
  fc.frames = test::noiseCube(16, 16, {0.0, 0.0}, 1.0, 1);
  EXPECT_THROW(makeCpuBackend()->search(fc, grid, params, progress, cancel), InputError);
}

}  // namespace
}  // namespace st::search

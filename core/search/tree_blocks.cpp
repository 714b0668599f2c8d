// Velocity blocks of the CPU tree search (tree_search.hpp, issue 20): which split of the grid into blocks of
// neighbouring velocities the search runs, chosen by the additions each split would cost (tree_plan.hpp's
// treeAdditions of the blocks' plans, treeSubPlan) among those whose 1-row tiles fit the buffers.
#include <algorithm>

#include "st/search/tree_plan.hpp"
#include "st/search/tree_search.hpp"

namespace st::search {

std::size_t treeBlockSplitBytes(std::size_t totalBytes) {
  return std::clamp(totalBytes > 0 ? totalBytes : kTreeBuffersBytes, kTreeMinTileBudgetBytes, kTreeTileBudgetBytes);
}

namespace {

struct BlockCells {
  int ix0 = 0, iy0 = 0, nx = 0, ny = 0;  ///< first root velocity and size of a block
};

/// Block (bx, by) of `b` over a root grid of gx x gy velocities.
BlockCells blockCells(const TreeBlocks& b, int gx, int gy, int bx, int by) {
  const int ix0 = bx * b.blockNvx, iy0 = by * b.blockNvy;
  return {ix0, iy0, std::min(b.blockNvx, gx - ix0), std::min(b.blockNvy, gy - iy0)};
}

/// `b` (its split set) priced: additions of all blocks, a full block's rows, the largest tile. False, and
/// `b` left unpriced, when a block's 1-row tile exceeds splitBytes (unless `anyway`).
bool priceBlocks(const TreePlan& whole, int width, int height, std::size_t splitBytes, std::size_t tileBudget,
                 bool anyway, TreeBlocks& b) {
  const int gx = static_cast<int>(whole.nodes.front().x.v.size());
  const int gy = static_cast<int>(whole.nodes.front().y.v.size());
  b.additions = 0.0;
  b.tileBytes = 0;
  b.tileRows = 0;
  // Blocks come in at most 4 sizes (the full one, the last column's, the last row's and the corner's): the
  // first block of each size is priced for all of them.
  for (int sy = 0; sy < 2; ++sy) {
    const int manyY = sy == 0 ? b.blocksY - 1 : 1;
    for (int sx = 0; sx < 2 && manyY > 0; ++sx) {
      const int manyX = sx == 0 ? b.blocksX - 1 : 1;
      if (manyX == 0) continue;
      const BlockCells c = blockCells(b, gx, gy, sx == 0 ? 0 : b.blocksX - 1, sy == 0 ? 0 : b.blocksY - 1);
      const TreePlan owned = b.count() == 1 ? TreePlan{} : treeSubPlan(whole, c.ix0, c.nx, c.iy0, c.ny);
      const TreePlan& plan = b.count() == 1 ? whole : owned;
      if (!anyway && treeTileBytes(plan, width, 1) > splitBytes) return false;
      const int rows = treeTileRows(plan, width, tileBudget);
      if (b.tileRows == 0) b.tileRows = rows;
      b.tileBytes = std::max(b.tileBytes, treeTileBytes(plan, width, rows));
      b.additions += static_cast<double>(manyX) * manyY * treeAdditions(plan, width, height, rows);
    }
  }
  return true;
}

}  // namespace

TreeBlocks treeVelocityBlocks(const TreePlan& whole, int width, int height, std::size_t splitBytes,
                              std::size_t tileBudgetBytes) {
  TreeBlocks best;
  if (whole.nodes.empty() || width <= 0 || height <= 0) return best;
  const int gx = static_cast<int>(whole.nodes.front().x.v.size());
  const int gy = static_cast<int>(whole.nodes.front().y.v.size());
  best.blockNvx = gx;
  best.blockNvy = gy;
  int tried = 0;  // splits priced since the first that fits
  bool found = false;
  int lastNvx = 0, lastNvy = 0;
  for (int k = 1; k <= std::max(gx, gy) && tried < kTreeBlockSplitsTried; ++k) {
    TreeBlocks b;
    b.blockNvx = (gx + k - 1) / k;
    b.blockNvy = (gy + k - 1) / k;
    if (b.blockNvx == lastNvx && b.blockNvy == lastNvy) continue;  // the same blocks as k - 1
    lastNvx = b.blockNvx;
    lastNvy = b.blockNvy;
    b.blocksX = (gx + b.blockNvx - 1) / b.blockNvx;
    b.blocksY = (gy + b.blockNvy - 1) / b.blockNvy;
    // Nothing fits, not even single velocities: those (as before).
    const bool last = !found && b.blockNvx == 1 && b.blockNvy == 1;
    if (!priceBlocks(whole, width, height, splitBytes, tileBudgetBytes, last, b)) continue;
    if (found) ++tried;
    if (!found || b.additions < (1.0 - kTreeBlockMinSaving) * best.additions) best = b;
    found = true;
  }
  return best;
}

VelocityGrid treeBlockGrid(const VelocityGrid& grid, const TreeBlocks& blocks, int bx, int by, int& ix0,
                           int& iy0) {
  ix0 = bx * blocks.blockNvx;
  iy0 = by * blocks.blockNvy;
  const int nx = std::min(blocks.blockNvx, grid.nvx - ix0), ny = std::min(blocks.blockNvy, grid.nvy - iy0);
  // The block's cell j is the grid's cell i0 + j: its centre sits (i0 + (n - 1) / 2) - (N - 1) / 2 steps away.
  const Velocity c{grid.centre.vx + (ix0 + 0.5 * (nx - 1) - 0.5 * (grid.nvx - 1)) * grid.stepPxS,
                   grid.centre.vy + (iy0 + 0.5 * (ny - 1) - 0.5 * (grid.nvy - 1)) * grid.stepPxS};
  return VelocityGrid{c, grid.stepPxS, nx, ny};
}

}  // namespace st::search

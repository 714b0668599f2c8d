#pragma once
// The hierarchical ("tree") velocity search on the CPU: the same SearchResult as the exact backend
// (cpu_backend.hpp), computed in about a few N_pix x N_v + N_pix x N_f additions instead of
// N_pix x N_f x N_v (plan and accuracy: tree_plan.hpp).
//
// Execution: the image is cut into tiles of rows; each tile is evaluated depth-first over the tree (a node's
// partial stacks, one per node velocity used by some root velocity, each only over the rows and columns its
// parents read; a leaf, or a node with a single velocity, is summed directly from its frames along its
// implied shifts), the children's stacks freed once the parent's are built. The root's stacks are not stored:
// each root velocity's sum over the tile is scanned at once for the velocity map and the cells above
// threshold. Tiles are spread over st::workerCount() threads. N_in: in closed form from the exact shifts
// round(v dt_k) (as the exact backend), so SNR = S / (sigma_F sqrt(N_in)) uses the same normalisation; the
// tree's samples deviate from the exact ones by at most TreePlan::maxAbsErr* px (tested <= 1). Memory: per
// thread about treeTileBytes(plan, width, tileRows) of partial stacks (the depth-first peak; held in a
// per-thread pool of reused buffers, best fit, so a little more), tileRows chosen as the largest <= 64 whose
// peak fits treeTileBudgetPerThread(threads, SearchParams::bufferBytes) (at least 1 row), plus 12 bytes per velocity for the map and (width +
// height) x (nvx + nvy) x 8 bytes of N_in ranges. Thresholds, minimum frames, capping and clustering: exactly
// the exact backend's (search_run.hpp, candidates.hpp). Cancellation polled per row of node velocities;
// progress per tile. Measured (`synthtrack-cli bench search --method tree`, 2-core AMD EPYC dev machine,
// shared, load ~8, 2026-11-22): the paper problem 1500 x 512^2 x 100^2 in 15.4 s wall / 7.7 CPU-s, 1.2e10
// additions (322x fewer than exact), tiles of 6 rows, peak RSS 2.38 GB with the 1.57 GB cube.
#include "st/search/tree_plan.hpp"
#include "st/search/types.hpp"

namespace st::search {

/// Partial-stack budget of one thread's tile at most (bytes): with 2 threads the paper problem stays within
/// the exact search's rule (1.5 x the cube + 300 MB).
inline constexpr std::size_t kTreeTileBudgetBytes = std::size_t{320} << 20;
/// Partial stacks of ALL threads together, by default (issue 20): the working set does not grow with the
/// thread count (16 threads used to hold 16 x 320 MB). Each thread gets this / threads, between
/// kTreeMinTileBudgetBytes and kTreeTileBudgetBytes (SearchParams::bufferBytes replaces it).
inline constexpr std::size_t kTreeBuffersBytes = 2 * kTreeTileBudgetBytes;
/// The smallest share of one thread (the stated per-thread term of the tree search's working set).
inline constexpr std::size_t kTreeMinTileBudgetBytes = std::size_t{24} << 20;

/// The row count of a tile for this plan: the most rows (<= 64) whose partial stacks fit `tileBudgetBytes`.
int treeTileRows(const TreePlan& plan, int width, std::size_t tileBudgetBytes = kTreeTileBudgetBytes);

/// One thread's tile budget when `threads` share `totalBytes` (0: kTreeBuffersBytes), clamped to
/// [kTreeMinTileBudgetBytes, kTreeTileBudgetBytes].
std::size_t treeTileBudgetPerThread(unsigned threads, std::size_t totalBytes = 0);

/// Velocity blocks (issue 20): the tree's partial stacks grow with the square of the grid's side (a 1-row
/// tile of 2000 x 1024 px needs 10.1 GB at 801^2 velocities, 152 MB at 101^2), so a grid whose 1-row tile
/// exceeds treeBlockSplitBytes is searched in blocks of neighbouring velocities, one tree each, and a grid
/// whose tiles would be only a few rows tall may be too (taller tiles in smaller blocks read fewer margin
/// rows: treeVelocityBlocks). Each block runs the whole tree's plan cut to its velocities (treeSubPlan), so
/// the values, cells and velocity map are those of one tree over the whole grid, bit for bit, whatever the
/// blocks; the blocks repeat the coarse levels' work that one tree shares.
struct TreeBlocks {
  int blocksX = 1, blocksY = 1;      ///< blocks along vx and vy
  int blockNvx = 0, blockNvy = 0;    ///< velocities of a full block (the last ones may have fewer)
  int tileRows = 0;                  ///< a full block's tile rows (treeTileRows of its plan)
  std::size_t tileBytes = 0;         ///< one thread's partial stacks at those rows, the largest block's
  double additions = 0.0;            ///< treeAdditions of all blocks together (the estimate they were chosen by)
  [[nodiscard]] int count() const noexcept { return blocksX * blocksY; }
};

/// The 1-row tile size above which the grid is split: the search buffers `totalBytes` (0: kTreeBuffersBytes)
/// clamped to [kTreeMinTileBudgetBytes, kTreeTileBudgetBytes], whatever the thread count (the paper's
/// problem, ~75 MB a row, stays one tree with the default buffers; a small memory budget splits sooner).
std::size_t treeBlockSplitBytes(std::size_t totalBytes);

/// How many splits treeVelocityBlocks prices beyond the fewest that fit.
inline constexpr int kTreeBlockSplitsTried = 6;
/// More blocks are taken only for at least this fraction fewer additions: each block re-plans, re-reads the
/// frames and holds taller tiles (more memory), which the additions do not count.
inline constexpr double kTreeBlockMinSaving = 0.05;

/// The velocity blocks of the cheapest tree search of `whole`'s grid over width x height px: both axes split
/// alike into k parts, k from the fewest whose largest block's 1-row tile fits `splitBytes` to
/// kTreeBlockSplitsTried more (distinct block sizes only); each priced by its blocks' treeAdditions at
/// treeTileRows(block plan, width, tileBudgetBytes) rows (a block of each size, the first one, stands for all
/// of that size); the fewest additions win, more blocks only by kTreeBlockMinSaving. `whole`: buildTreePlan
/// of the grid.
TreeBlocks treeVelocityBlocks(const TreePlan& whole, int width, int height, std::size_t splitBytes,
                              std::size_t tileBudgetBytes);

/// Block (bx, by)'s grid: its cell j is `grid`'s cell (ix0 + jx, iy0 + jy).
VelocityGrid treeBlockGrid(const VelocityGrid& grid, const TreeBlocks& blocks, int bx, int by, int& ix0,
                           int& iy0);

/// Runs the tree search. Validates like the exact backend (validateSearchInput); result.method = "tree",
/// result.backend = "cpu". Throws st::InputError, st::Cancelled.
SearchResult treeSearch(const FilteredCube& cube, const VelocityGrid& grid, const SearchParams& params,
                        ProgressSink& progress, CancelToken& cancel);

}  // namespace st::search

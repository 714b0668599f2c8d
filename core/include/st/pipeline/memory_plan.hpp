#pragma once
// Peak-memory estimates of an observation's paths and the choice between in memory and out of core
// (issue 20). Every estimate is a typed MemoryEstimate with its parts, printed with the plan before any
// pixel is read; the run then either fits its budget in memory, or runs out of core in tiles
// (search/tiled_search.hpp) sized from the budget, or stops with st::InputError naming the need and the
// budget (nothing killed by the kernel).
//
// The terms (bytes; N frames of W x H px, "sample" = one pixel of one frame):
// - in-memory pre-processing of raw frames: the cube 4/sample, its pixel mask 1/sample (hot pixels, BLANK),
//   the zero-biased copy 4/sample only when it is kept (--fit; otherwise the matched filter runs in place),
//   kPreprocessImageBytesPerPixel per frame pixel (background, noise, stacks, masks, filter weights) and
//   kPreprocessBytesPerFrame per frame,
//   per-thread row buffers of the per-pixel background (min(N, 2000) x W x 32) and
//   kPreprocessThreadBytesPerPixel per frame pixel (the thread's frame buffers);
// - a search: the filtered cube 4/sample (+ mask), the backend's working set (MethodEstimate: exact kernel
//   scratch, or the tree's partial stacks sized by SearchParams::bufferBytes), the map and the cells above
//   threshold (kHitBytes each, at most maxCandidates, kExpectedHits assumed);
// - out of core: one tile's read area x N x (4 + 1) plus the loader's plane buffers and the search working
//   set of a tile; the per-thread term is the loader's one plane of a tile (5 bytes a pixel) and the exact
//   kernel's scratch (~0.3 MB at 512 px) or the tree's share of bufferBytes.
#include <cstddef>
#include <string>
#include <vector>

#include "st/common/memory_budget.hpp"
#include "st/search/method_choice.hpp"
#include "st/search/tiled_search.hpp"

namespace st::pipeline {

/// Frame-sized images held by the in-memory pre-processing (background, noise, stacks on their canvases,
/// masks, filter weights), bytes per frame pixel, and per-frame records (frame backgrounds, meshes), bytes
/// per frame. Fitted to VmHWM of `search` on simulated cubes (2-core VM, 2026-11-25): 200 x 512^2 346 MB,
/// 400 x 256^2 173 MB, 100 x 1024x512 421 MB are ~300 B/px + 5 B/sample + ~21 MB; the constants are
/// rounded up so that the estimate is 10-15% above those peaks.
inline constexpr double kPreprocessImageBytesPerPixel = 320.0;
inline constexpr double kPreprocessBytesPerFrame = 32.0 * 1024;
/// Frame-sized buffers each pre-processing thread holds (a frame's FFT and SEP buffers, stack bands), bytes
/// per frame pixel. Measured 2026-11-27 (dev VM): strips of 256 x 448 px x 100 frames peaked at 148 MB
/// with 2 threads and 231 MB with 16 (5.1 MB more per thread, 44 B per frame pixel, beyond the 4 B counted
/// before); 56 leaves a margin.
inline constexpr double kPreprocessThreadBytesPerPixel = 56.0;
/// Bytes held per cell above threshold (CellHit plus sorting and clustering).
inline constexpr double kHitBytes = 80.0;
/// Cells above threshold assumed by the estimate (a field with bright residuals; at most maxCandidates).
inline constexpr double kExpectedHits = 200000.0;
/// Allocator and library overhead counted in every estimate (code, CFITSIO buffers, heap slack).
inline constexpr double kBaseBytes = 48.0 * 1024 * 1024;

struct CubeShape {
  int width = 0;
  int height = 0;
  std::size_t frames = 0;
  [[nodiscard]] double samples() const {
    return static_cast<double>(width) * static_cast<double>(height) * static_cast<double>(frames);
  }
};

/// Peak of pre-processing raw frames in memory (preprocess.hpp). `keepZeroBiased`: the zero-biased cube is
/// kept beside the filtered one (search --fit, preprocess -o with --filtered).
MemoryEstimate estimatePreprocessPeak(const CubeShape& shape, bool keepZeroBiased, unsigned threads);

/// Peak of searching a filtered cube of `shape` held in memory with method `method` (Exact or Tree),
/// `estimate` from search::estimateMethods for that shape.
MemoryEstimate estimateSearchPeak(const CubeShape& shape, const search::MethodEstimate& estimate,
                                  search::SearchMethod method);

/// The out-of-core plan of a search: tiles, overlap and one tile's estimate.
struct TiledSearchPlan {
  std::vector<search::SearchTile> tiles;  ///< empty: not even the smallest tile fits
  int overlapPx = 0;
  MemoryEstimate perTile;       ///< the peak while the largest tile is searched
  MemoryEstimate smallestTile;  ///< the need of the smallest tile (for the message when none fits)
  /// The tree's threads (SearchParams::treeThreads): estimate.treeBusyThreads, fewer when their partial
  /// stacks would take more than half of what the budget leaves beside the base and the cells (at least 1).
  unsigned treeThreads = 0;
};

/// Tiles for a search of `shape` with `overlapPx` under `budgetBytes`; `estimate` prices the tile's
/// search working set (its per-thread scratch does not depend on the tile's height). The tree's threads
/// are lowered (treeThreads) when all of them would not leave room for a tile: the working set of the tree
/// grows by one tile of partial stacks per thread (~22 MB a thread for 81^2 velocities x 100 frames x
/// 256 px wide), which 16 threads cannot hold under a 170 MB budget.
TiledSearchPlan planTiledSearch(const CubeShape& shape, int overlapPx, std::size_t budgetBytes,
                                const search::MethodEstimate& estimate, search::SearchMethod method,
                                unsigned threads);

/// The search buffers (SearchParams::bufferBytes) a budget allows: a quarter of it, at most the default
/// kTreeBuffersBytes, at least kTreeMinTileBudgetBytes.
std::size_t searchBufferBytes(std::size_t budgetBytes);

/// The message when even one tile (or the in-memory path that cannot be tiled) does not fit: names what is
/// needed, the budget and its source, and what to do.
std::string overBudgetMessage(const std::string& what, const MemoryEstimate& need, const MemoryBudget& budget);

}  // namespace st::pipeline

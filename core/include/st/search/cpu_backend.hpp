#pragma once
// The CPU search backend: exact IPSA over the whole velocity grid, on all cores. The reference every other
// backend is checked against.
//
// search(): validates the input (validateSearchInput), computes for every grid velocity and pixel
// S = sum_n F_n(x + round(vx dt_n), y + round(vy dt_n)) with N_in in closed form (ipsa.hpp), SNR =
// S / (sigma_F sqrt(N_in)), ignores cells with N_in < minFramesFor(params, frames), and returns
// - map: per velocity the highest SNR over pixels and its (x, y) (0 and (-1, -1) where no cell qualified);
// - candidates: cells with SNR > threshold (params.snrThreshold, or the inverse of Prob_false for
//   params.targetFap with the full trial counts), the params.maxCandidates best kept, clustered with
//   clusterCells(defaultClusterParams(cube.psfFwhmPx)) (candidates.hpp), each with its Prob_false;
// - trials (width, height, nvx, nvy), the threshold used, cellsAboveThreshold (before the cap), t_ref.
// Work: tiled and vectorised (core/search/ipsa_kernel.hpp); st::parallelFor over (velocity block x row
// tile) items; cancellation polled every 8 frames of an item (well under 1 ms); progress per item.
// Memory: the cube is read in place; per thread ~0.5 MB of tiles and accumulators, plus 12 bytes per
// velocity for the map (estimateSearch in velocity_grid.hpp).
//
// supportsMethod(): "exact" and "tree" (params.method "tree" runs treeSearch, tree_search.hpp).
// stackAt(): the IPSA sum image at one velocity (st::stack::stackIpsa); CSA throws st::InputError
// "CSA not supported by this backend".
#include <memory>

#include "st/search/types.hpp"

namespace st::search {

/// A new CPU exact backend. Its name() is "cpu (N threads)", N = st::workerCount().
std::unique_ptr<SearchBackend> makeCpuBackend();

}  // namespace st::search

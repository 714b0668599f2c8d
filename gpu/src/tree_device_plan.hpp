#pragma once
// Host side of the CUDA tree search: a search::TreePlan flattened into the tables of tree_kernel_params.hpp
// for tiles of `tileRows` image rows (every tile uses the same tables; only y0 changes).
//
// Which nodes run: the root is never stored; the nodes at depth `cut` (1..kTreeMaxCut) are summed in
// registers by the root kernel, so the levels above them are never stored either (at the top of the tree
// each node velocity is used by about one parent velocity, so storing them would only add memory traffic).
// Below the cut every node on a root path is built, level by level (a direct node is summed from its frames
// and its subtree is skipped, as on the CPU). Levels alternate between two arenas.
#include <cstddef>
#include <vector>

#include "st/search/tree_plan.hpp"
#include "tree_kernel_params.hpp"

namespace st::gpu {

struct TreeDeviceLevel {
  int depth = 0;
  int jobBegin = 0;  ///< jobs [jobBegin, jobEnd) of TreeDevicePlan::jobs
  int jobEnd = 0;
  int rowBegin = 0;  ///< rows [rowBegin, rowEnd) of TreeDevicePlan::rowJobs
  int rowEnd = 0;
  int arena = 0;  ///< 0 or 1: output arena; input is the other one
};

struct TreeDevicePlan {
  int width = 0;
  int height = 0;
  int tileRows = 0;
  int tiles = 0;
  int cut = 1;
  std::vector<TreeDeviceLevel> levels;  ///< deepest first; the last one is at depth `cut`
  std::vector<TreeJob> jobs;
  std::vector<int2> rowJobs;
  std::vector<int4> segTab;
  std::vector<int2> rowTab;
  std::vector<int> shiftX, shiftY;
  std::vector<int> frameIndex;
  std::size_t arenaFloats[2] = {0, 0};
  // Root tables.
  std::vector<long long> cutBase;
  std::vector<int> cutPitch;
  std::vector<int> colBase;
  std::vector<int> rowBase;
  int nvx = 0;
  int nvy = 0;
  double additionsPerTile = 0.0;  ///< additions and copies of one tile (levels + root)

  [[nodiscard]] std::size_t arenaBytes() const { return (arenaFloats[0] + arenaFloats[1]) * sizeof(float); }
  [[nodiscard]] std::size_t tableBytes() const;
};

/// Flattens `plan` for an image of width x height in tiles of `tileRows` rows, the top levels down to depth
/// `cut` summed by the root kernel (lowered so that no node above the cut is direct). Throws st::GpuError if
/// a parent would read outside its child's stacks (a plan inconsistency).
TreeDevicePlan makeTreeDevicePlan(const search::TreePlan& plan, int width, int height, int tileRows, int cut);

/// The largest cut <= wanted (>= 1) with no direct node above it.
int treeCut(const search::TreePlan& plan, int wanted);

}  // namespace st::gpu

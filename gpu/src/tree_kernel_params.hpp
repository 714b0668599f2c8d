#pragma once
// Plain structs of the CUDA tree search (tree_kernels.cu), C++17, no core headers. The host side
// (tree_device_plan.cpp) flattens a search::TreePlan into these tables.
//
// Layout of a node's partial stacks on the device (a "mosaic"): one 2-D array per node whose columns are the
// x segments of its used x velocities side by side (segment jx holds positions [reachLo, width + reachHi)
// of that velocity, tree_plan.hpp) and whose rows are the y segments of its used y velocities, one above the
// other (positions [reachLo, tileRows + reachHi), tile-relative). Stack (jx, jy) is the block where its
// segments cross. Because every grid of the tree is a product grid, a parent's column and row of a child's
// mosaic depend only on the parent's column and row: per node, one segment list (columns) and one row table.
#include <cuda_runtime.h>

#include <cstddef>
#include <cstdint>

#include "kernel_params.hpp"

namespace st::gpu {

/// One node evaluated by a level launch.
struct TreeJob {
  long long out;    ///< float offset of the node's mosaic in the output arena
  long long left;   ///< combine: float offsets of the children's mosaics in the input arena
  long long right;  ///<
  int pitch;        ///< mosaic columns
  int leftPitch;    ///< combine: children's mosaic columns
  int rightPitch;
  int segTable;  ///< offset in TreeLevelLaunch::segTab of this node's column segments (one per used x
                 ///< velocity)
  int segments;  ///< number of segments
  int rowTable;  ///< offset in TreeLevelLaunch::rowTab: per row (left row, right row) or, direct, (jy, y)
  int direct;    ///< 1: summed from its frames along its implied shifts
  int first;     ///< direct: time-ordered frames [first, last)
  int last;
  int shiftX;  ///< direct: offset in TreeLevelLaunch::shiftX of [node x velocity][frame - first] (absolute
               ///< px)
  int shiftY;
};

/// One level of the tree over one tile of rows: every warp builds one mosaic row of one job, segment by
/// segment.
struct TreeLevelLaunch {
  const float* frames;    ///< the cube, resident, cube frame order
  const int* frameIndex;  ///< cube frame of the k-th frame in time order
  int width;
  int height;
  int y0;  ///< first image row of the tile
  const TreeJob* jobs;
  const int2* rowJobs;  ///< [rows of this level] (job, mosaic row)
  int rows;
  const int4*
      segTab;  ///< (out column, length, left column, right column) or, direct, (out column, length, jx, x)
  const int2* rowTab;
  const int* shiftX;
  const int* shiftY;
  const float* in;   ///< arena of the level below
  float* out;        ///< arena of this level
  bool directPlain;  ///< benchmarks: direct nodes frame by frame from the tables (the path before 2026-11-27)
};

/// The root over one tile: each root velocity's stack is the sum of 2^cut mosaics of the nodes at depth
/// `cut` (the top levels are summed in registers, in the tree's pairwise order), scanned at once.
struct TreeRootLaunch {
  const float* in;           ///< arena of the cut level
  const long long* cutBase;  ///< [2^cut] float offset of each cut node's mosaic
  const int* cutPitch;       ///< [2^cut]
  const int* colBase;        ///< [2^cut][nvx] mosaic column of image column 0 for root vx
  const int* rowBase;        ///< [2^cut][nvy] mosaic row of tile row 0 for root vy
  int cut;                   ///< 1..kTreeMaxCut
  int shape;  ///< root velocities per block (vx x vy), columns per thread, register bound: 0 = 4 x 4, 2
              ///< columns,
              ///< <= 128 registers (default); 1 = 8 x 8; 2 = 2 x 4; 3 = 4 x 8; 4 = 4 x 4 at <= 64 registers;
              ///< 5 = 4 x 4 unbounded; 6 = 4 x 4 at <= 80 registers; 7 = 4 x 4, 2 columns, <= 102 registers;
              ///< 8 = 4 x 4, 4 columns; 9 = 8 x 4, 2 columns; 10, 13 = 2 x 4, 2 columns, <= 80 or 64
              ///< registers; 11 = 4 x 8, 2 columns; 12 = 4 x 2, 2 columns (1 column unless said)
  int width;
  int height;
  int y0;
  int tileRows;
  int nvx;
  int nvy;
  const int2* spanX;  ///< as SearchLaunch (N_in from the exact shifts)
  const int2* spanY;
  const unsigned* maskX;  ///< as SearchLaunch (registered frames), or null
  const unsigned* maskY;
  int maskWords;
  const float* invNorm;
  float snrThreshold;
  int minFrames;
  unsigned long long* mapKeys;  ///< [nvy][nvx]
  DeviceCell* cells;
  unsigned long long* cellCount;
  unsigned long long cellCapacity;
};

/// Floats one arena may hold: the root kernel indexes the cut level's arena with 32-bit offsets (tiles of
/// fewer rows are taken when a level would need more).
inline constexpr std::size_t kTreeMaxArenaFloats = (std::size_t{1} << 31) - 4096;
/// Floats allocated past each arena's end: the root kernel's lanes past the image's right edge read (and
/// skip) up to 63 columns past a mosaic row, the last one included.
inline constexpr std::size_t kTreeArenaSlack = 64;
/// Deepest level summed in registers by the root kernel.
inline constexpr int kTreeMaxCut = 4;
/// Rows of the tile one root block scans.
inline constexpr int kTreeRootRows = 32;

/// Loads the tree kernels' module on the current device (lazy loading would load it at the first level's
/// launch, inside the timed kernels: 5-10 ms on the first tree search of a process, H100 2026-11-27).
void loadTreeKernels();
void launchTreeLevel(const TreeLevelLaunch& p, cudaStream_t stream);
void launchTreeRoot(const TreeRootLaunch& p, cudaStream_t stream);

}  // namespace st::gpu

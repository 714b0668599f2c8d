#pragma once
// Private to core/search: the tiled, vectorised exact IPSA kernel behind the CPU backend and confirmation.
//
// Design (read before changing):
// - Frames are visited in time order (sorted dt), so every shift sequence round(v dt_n) is monotone and the
//   frames whose sample lies inside the image form one contiguous range for each column and for each row:
//   N_in(x, y) = |range(x) ∩ range(y)| in closed form, no per-sample branch.
// - Work item = (block of kVelBlock velocities) x (tile of kRowTile output rows). Per item a thread keeps
//   kVelBlock x kRowTile accumulator rows (L2-resident) and walks the frames kFrameBlock at a time: the
//   rows those frames need are copied once into a zero-padded tile (zero rows outside the image, kPad
//   zero columns either side), so every (velocity, row) adds kFrameBlock contiguous, branch-free rows into
//   its accumulator row, with the accumulator held in SIMD registers across the frame block.
// - Exceptions (st::Cancelled) propagate through st::parallelFor; cancellation is polled every frame block
//   (well under a millisecond of work).
#include <cstddef>
#include <cstdint>
#include <vector>

#include "st/common/frame_cube.hpp"
#include "st/common/progress.hpp"
#include "st/search/candidates.hpp"
#include "st/search/types.hpp"

namespace st::search::detail {

inline constexpr int kVelBlock = 32;
inline constexpr int kRowTile = 4;
inline constexpr int kFrameBlock = 8;

/// Output region, image pixels [x0, x0 + width) x [y0, y0 + height).
struct Roi {
  int x0 = 0;
  int y0 = 0;
  int width = 0;
  int height = 0;
};

struct KernelParams {
  double sigmaF = 1.0;        ///< noise of one filtered frame
  double snrThreshold = 7.0;  ///< cells strictly above are reported
  int minFrames = 1;          ///< cells with N_in below are ignored
  std::size_t maxHits = 10000;
  /// Rows of the velocity grid searched: [ivyBegin, ivyEnd), -1 = to the last (search --mpi gives each rank
  /// its share). Cells and map entries of other rows are left out; results of a row do not depend on which
  /// other rows are searched with it (each velocity's sums run over the frames in the same order).
  int ivyBegin = 0;
  int ivyEnd = -1;
};

/// A velocity map of `grid` with no maximum yet (SNR 0, argX/argY -1): filled by merging searches of parts
/// (tiles, velocity blocks, rows of the grid).
inline VelocityMap emptyVelocityMap(const VelocityGrid& grid) {
  VelocityMap map;
  map.nvx = grid.nvx;
  map.nvy = grid.nvy;
  map.maxSnr.assign(grid.count(), 0.0f);
  map.argX.assign(grid.count(), -1);
  map.argY.assign(grid.count(), -1);
  return map;
}

struct KernelOutput {
  VelocityMap map;
  std::vector<CellHit> hits;   ///< the highest-SNR cells above threshold, at most maxHits, unsorted
  std::int64_t hitsTotal = 0;  ///< every cell above threshold, before the maxHits cap
};

/// Runs the exact search over `grid` for output pixels in `roi`. Throws st::Cancelled.
KernelOutput runIpsaKernel(const FrameCube& cube, const VelocityGrid& grid, const Roi& roi,
                           const KernelParams& params, ProgressSink& progress, CancelToken& cancel);

/// Bytes the kernel allocates on top of the cube (scratch per thread, map, hit buffers).
std::size_t workingBytes(int width, int height, std::size_t frames, const VelocityGrid& grid,
                         unsigned threads);

/// acc[0, wp) += sum_k src[k][0, wp); wp a multiple of 8. AVX2 when the CPU has it.
void addRows(float* acc, const float* const* src, int count, int wp);

/// The largest of a[0, n) (n >= 1). AVX2 when the CPU has it.
float maxOf(const float* a, int n);

}  // namespace st::search::detail

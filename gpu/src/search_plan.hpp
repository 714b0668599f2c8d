#pragma once
// Host side of the CUDA search: converts the core types (FilteredCube, VelocityGrid, SearchParams) into the
// plain tables the kernels read (shifts, N_in spans, normalisation) and chooses the kernel tiling.
#include <cstddef>
#include <string>
#include <vector>

#include "st/search/types.hpp"

namespace st::gpu {

struct HostPlan {
  int width = 0;
  int height = 0;
  int frameCount = 0;
  int nvx = 0;
  int nvy = 0;
  std::vector<int> shiftX;  ///< [nvx][N] round(vx dt_n), halves away from zero (std::lround)
  std::vector<int> shiftY;  ///< [nvy][N]
  std::vector<int> spanX;   ///< [nvx][W][2] inclusive range of time-ordered frames keeping column x in frame
  std::vector<int> spanY;   ///< [nvy][H][2] same for rows
  /// Registered frames only (else empty): [nvx][W][maskWords] and [nvy][H][maskWords] bit masks of the
  /// frames keeping the column / row in frame (SearchLaunch::maskX).
  std::vector<unsigned> maskX, maskY;
  int maskWords = 0;
  std::vector<float> invNorm;  ///< [N + 1] float(1 / (sigma_F sqrt(n)))
  float snrThreshold = 0.0f;   ///< cells strictly above are candidates
  int minFrames = 1;           ///< cells with fewer contributing frames are ignored
  /// Which search kernel runs: the row kernel when its conditions hold (kernel_params.hpp), else the tiled
  /// kernel, else (shift spread too large for shared memory) the naive kernel; same results, slower.
  /// The stair kernel (neighbouring vy at most 1 px apart at every frame) is preferred over both.
  enum class Kernel { Stair, Row, Tiled, Naive };
  Kernel kernel = Kernel::Tiled;
  // Tiling of the tiled kernel.
  int vtileX = 8;
  int vtileY = 1;
  int pitch = 0;
  int winRows = 0;
  int framesPerStage = 1;
  int rowGroups = 1;       ///< row kernel: groups of 8 velocities per block
  int stairRows = 8;       ///< stair kernel: pixel rows per block (8: two blocks per SM, 4: four)
  bool stairTma = true;    ///< stair kernel, 8 rows: windows copied by the TMA (when the driver allows)
  bool stairPipe = false;  ///< stair kernel, 8 rows, TMA: software-pipelined frame loop (slower, kept)
  int tiledMode = 0;       ///< inner loop of the tiled kernel (SearchLaunch::variant)
  /// Stair kernel, 8 rows, FramePrecision::Float16 (chooseStairHalf): frames read from a half-precision
  /// copy of the resident cube, pairs of columns (x, x + 32) in one 4-byte word, summed in half over the
  /// frames of one stage (framesPerStage) and in float across stages.
  bool halfFrames = false;
  int halfFramesPerStage = 0;  ///< Float16: frames per stage (framesPerStage stays the float kernel's)
  float halfScale = 1.0f;      ///< Float16: frames multiplied by this power of two (~1 / sigma_F) first
  double sigmaF = 1.0;
};

/// Builds the tables for `cube` and `grid`. `threshold` is the SNR threshold actually used and
/// `minFrames` the N_in floor (both as the CPU backend derives them). Throws st::InputError on bad input.
HostPlan makeHostPlan(const search::FilteredCube& cube, const search::VelocityGrid& grid, double threshold,
                      int minFrames);

/// Chooses the kernel and its tiling for `plan` (done by makeHostPlan with allowStair, allowRow,
/// !preferRow). allowStair takes the stair kernel whenever it applies; otherwise allowRow false forces the
/// tiled (or naive) kernel and preferRow takes the row kernel whenever it applies.
void chooseTiling(HostPlan& plan, bool allowRow, bool preferRow, bool allowStair = false);

/// True when the stair kernel applies to `plan`: width a multiple of 4 and neighbouring vy at most 1 px
/// apart at every frame; sets its pitch and frames per stage for `rows` (8 or 4) pixel rows per block.
bool chooseStair(HostPlan& plan, int rows = 8);

/// Switches a stair plan of 8 rows (not pipelined) to half-precision frames, at most `maxFramesPerStage`
/// frames per stage (0: kStairHalfDefaultStage); false, plan unchanged, when it does not apply.
bool chooseStairHalf(HostPlan& plan, int maxFramesPerStage);

/// Checks what the CUDA backend needs beyond st::search::validateSearchInput (pixel buffer size, frame
/// count); throws st::InputError naming the value.
void validateForGpu(const search::FilteredCube& cube);

}  // namespace st::gpu

#pragma once
// Plain parameter structs that cross into the .cu files (C++17, no core headers). The host side
// (search_plan.cpp) converts the core types (FilteredCube, VelocityGrid, SearchParams) into these.
#include <cuda_runtime.h>

#include <cstddef>
#include <cstdint>
#include <cstring>

namespace st::gpu {

/// One raw cell above threshold, appended by the search kernel into a bounded device buffer.
struct DeviceCell {
  int x;
  int y;
  int ivx;
  int ivy;
  float sum;
  float snr;
  int nIn;
  int pad;
};

/// What the tiled search kernel and the naive reference kernel need. All pointers are device pointers.
struct SearchLaunch {
  const float* frames;  ///< frames [f0Resident, ...) resident on the device, frame-major, W*H each
  int frameBase;        ///< index of the first resident frame (frames[0] is frame frameBase)
  int width;
  int height;
  int frameCount;     ///< N_f of the whole cube
  int f0;             ///< first frame of this launch (absolute index)
  int f1;             ///< one past the last frame of this launch
  const int* shiftX;  ///< [nvx][frameCount] round(ox_n + vx * dt_n)
  const int* shiftY;  ///< [nvy][frameCount] round(oy_n + vy * dt_n)
  const int2* spanX;  ///< [nvx][width]  frames (in time order) whose x-shift keeps column x in frame
  const int2* spanY;  ///< [nvy][height] same for rows
  /// Registered frames (shifts not monotone in time, spans meaningless): N_in = popcount(maskX & maskY),
  /// maskX [nvx][width][maskWords] bit n set when frame n's x-shift keeps column x in frame, maskY the same
  /// for rows. Null when the frames carry no registration offsets (N_in from the spans).
  const unsigned* maskX;
  const unsigned* maskY;
  int maskWords;
  int nvx;
  int nvy;
  int iy0;  ///< velocity chunk: rows [iy0, iy1) of the grid
  int iy1;
  float* partial;                 ///< [chunk velocities][H][W] partial sums across frame chunks, or null
  bool loadPartial;               ///< add partial[] to the accumulators before the first frame
  bool finalize;                  ///< last frame chunk: compute SNR, reduce the map, append candidates
  const float* invNorm;           ///< [frameCount + 1] float(1 / (sigma_F sqrt(n))), as the CPU backend uses
  float snrThreshold;             ///< cells with SNR strictly above are candidates (as the CPU backend)
  int minFrames;                  ///< cells with N_in below this are ignored (map and candidates)
  unsigned long long* mapKeys;    ///< [nvy][nvx] packed (ordered SNR bits, ~pixel index), atomicMax
  DeviceCell* cells;              ///< bounded candidate buffer
  unsigned long long* cellCount;  ///< number of cells found (may exceed cellCapacity: overflow)
  unsigned long long cellCapacity;
  // Tiling chosen by the host for the tiled kernel (ignored by the naive kernel).
  int vtileX;  ///< velocities per block along x (vtileX * vtileY == kVelPerBlock)
  int vtileY;
  int pitch;    ///< shared-memory row pitch (floats) of one frame window
  int winRows;  ///< rows of one frame window
  int framesPerStage;
  int groups;      ///< row kernel: groups of kRowVelocities velocities per block (8, 4, 2, 1)
  int variant;     ///< tiled kernel: inner loop 0 reuse by branch, 1 no reuse, 2 reuse by predicates;
                   ///< + 10: 2 columns per thread (64-wide tiles, 4 blocks per SM)
  int stairRows;   ///< stair kernel: pixel rows per block, 8 or 4
  bool stairTma;   ///< stair kernel, 8 rows: windows copied by the tensor memory accelerator
  bool stairPipe;  ///< stair kernel, 8 rows, TMA: next frame's rows loaded during this frame's additions
  const int* tileOffsets;  ///< [velocity tiles][frameCount][kVelPerBlock + 2] window origin + offsets
  /// Stair kernel, FramePrecision::Float16: the frames as half pairs (x, x + 32) of frame * halfScale,
  /// same frame indices as `frames`, rows of width + kStairHalfPad words (launchHalfPairs); null: float.
  const unsigned* framesHalf;
  float halfInvScale;  ///< 1 / halfScale (a power of two): sums are scaled back before scoring
};

/// The row kernel (row_search_kernel.cu): kRowVelocities consecutive vx of one vy per block; usable when
/// the frame width is a multiple of 4 and, at every frame, those velocities' x shifts span at most
/// kRowMaxOffset - 3 pixels.
inline constexpr int kRowVelocities = 8;
inline constexpr int kRowMaxOffset = 12;

/// Velocities one block of the tiled kernel accumulates in registers.
inline constexpr int kVelPerBlock = 8;
/// Block shape of the tiled kernel: 8 warps; each thread owns kColsPerThread columns (stride 32)
/// x kRowsPerThread rows (stride 8).
inline constexpr int kColsPerThread = 4;
inline constexpr int kRowsPerThread = 2;
inline constexpr int kTileW = 32 * kColsPerThread;
inline constexpr int kTileH = 8 * kRowsPerThread;
inline constexpr int kThreads = 256;

/// Packs an SNR and a pixel index so that a 64-bit max picks the highest SNR and, on ties, the lowest
/// index (the first in row-major order, as a sequential scan keeps it).
inline std::uint64_t hostUnpackIndex(unsigned long long key) {
  return 0xFFFFFFFFull - (key & 0xFFFFFFFFull);
}
inline float hostUnpackSnr(unsigned long long key) {
  std::uint32_t bits = static_cast<std::uint32_t>(key >> 32);
  bits = (bits & 0x80000000u) ? (bits & 0x7FFFFFFFu) : ~bits;
  float f;
  static_assert(sizeof(f) == sizeof(bits));
  std::memcpy(&f, &bits, sizeof(f));
  return f;
}

/// Launchers (search_kernels.cu). Each checks the launch and throws st::GpuError on failure.
void launchTileOffsets(const SearchLaunch& p, int* tileOffsets, int tileCount, cudaStream_t stream);
void launchTiledSearch(const SearchLaunch& p, cudaStream_t stream);
void launchNaiveSearch(const SearchLaunch& p, cudaStream_t stream);
/// Bytes of dynamic shared memory the tiled kernel needs for this tiling.
std::size_t tiledSharedBytes(int pitch, int winRows, int framesPerStage);
/// Raises the tiled kernel's dynamic shared-memory limit on the current device.
void configureTiledKernel(std::size_t sharedBytes);
/// Tile width (pixels) of the tiled kernel for SearchLaunch::variant (>= 10: 2 columns per thread).
int tiledTileWidth(int variant);

/// Row kernel launchers (row_search_kernel.cu); tileOffsets hold kRowVelocities + 2 ints per tile and frame.
void launchRowOffsets(const SearchLaunch& p, int* tileOffsets, int tileCount, cudaStream_t stream);
void launchRowSearch(const SearchLaunch& p, cudaStream_t stream);
/// Shared memory of the row kernel for a window of winRows x pitch floats.
std::size_t rowSharedBytes(int pitch, int winRows, int framesPerStage);
void configureRowKernel(std::size_t sharedBytes);
/// Velocity tiles of the row kernel (groups x 8 velocities each) for `rows` grid rows.
int rowTileCount(int nvx, int rows, int groups);
/// Ints per (tile, frame) in the row kernel's offset table.
std::size_t rowOffsetInts();

/// The stair kernel (stair_search_kernel.cu): a block owns kStairVx consecutive vx x kStairVy consecutive
/// vy and a (32 kStairCols) x (8 or 4) pixel tile; usable when the frame width is a multiple of 4 and, at
/// every frame, neighbouring vy of the grid shift by at most 1 px relative to each other.
inline constexpr int kStairVx = 8;
inline constexpr int kStairVy = 4;
inline constexpr int kStairCols = 2;
/// Shared-memory row stride (floats) of the stair kernel's window, a compile-time constant so that row
/// addresses are immediate offsets: the kernel applies while the 8 vx of a block stay within
/// kStairPitch - 32 kStairCols - 6 = 10 px of each other at every frame (always so when neighbouring
/// vy, hence vx on the grid's common step, are at most 1 px apart: the stair kernel's own condition).
/// 80 rather than 96: smaller windows, 16 frames per stage instead of 13 (H100, 2026-11-22).
inline constexpr int kStairPitch = 80;
void launchStairOffsets(const SearchLaunch& p, int* tileOffsets, int tileCount, cudaStream_t stream);
void launchStairSearch(const SearchLaunch& p, cudaStream_t stream);
/// Shared memory of the stair kernel for `framesPerStage` frames per stage and `rows` (8 or 4) pixel rows.
std::size_t stairSharedBytes(int framesPerStage, int rows);
void configureStairKernel(std::size_t sharedBytes, int rows);
/// Float16 stair kernel (8 rows): window row stride in 4-byte pairs (x, x + 32), 32 fewer than kStairPitch;
/// frames per stage by default (half sums over at most this many frames before a float flush).
inline constexpr int kStairHalfPitch = kStairPitch - 32;
inline constexpr int kStairHalfDefaultStage = 16;
inline constexpr int kStairHalfMaxStage = 28;
inline constexpr float kStairHalfClamp = 2048.0f;
/// Float16 frames: rows of width + kStairHalfPad words; word x + kStairHalfPad holds columns (x, x + 32) for
/// x in [-32, width), zero outside the frame (a window left of the frame still needs its columns x + 32).
inline constexpr int kStairHalfPad = 32;
/// Shared memory of the Float16 stair kernel (8 rows) for `framesPerStage` frames per stage.
std::size_t stairHalfSharedBytes(int framesPerStage);
/// Converts frames [f0, f1) of the float cube `frames` (width x height each) into half pairs
/// out[n][y][x + kStairHalfPad] = (half(frames[n][y][x] * scale), half(frames[n][y][x + 32] * scale)) for x
/// in
/// [-kStairHalfPad, width), zero outside the frame,
/// the scaled values clamped to +-kStairHalfClamp (no half overflow in a stage of <= 28 frames).
void launchHalfPairs(const float* frames, unsigned* out, int width, int height, int f0, int f1, float scale,
                     cudaStream_t stream);
/// Velocity tiles of the stair kernel for `rows` grid rows.
int stairTileCount(int nvx, int rows);
/// Ints per (tile, frame) in the stair kernel's offset table.
std::size_t stairOffsetInts();

/// IPSA stack of frames [0, frameCount) at integer shifts.
struct StackLaunch {
  const float* frames;
  int width;
  int height;
  int frameCount;
  const int* shiftX;  ///< IPSA: [frameCount]
  const int* shiftY;
  float* partial;  ///< [groups][H][W]
  int groups;
  float* out;  ///< [H][W]
};
void launchStack(const StackLaunch& p, cudaStream_t stream);

}  // namespace st::gpu

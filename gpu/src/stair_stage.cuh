#pragma once
// The stair kernel's per-frame additions (C++17, CUDA only; included by stair_search_kernel.cu): the 15
// staircase patterns of 4 vy, each a compile-time body of 4 x kSR x kSC additions selected by one switch
// per frame, plain (stairStage) or software-pipelined (stairStagePipe).
#include <cuda_fp16.h>

#include "kernel_params.hpp"

namespace st::gpu::stair {

constexpr int kSVx = kStairVx;           // warps per block, one vx each
constexpr int kSVy = kStairVy;           // vy per thread (staircase of 4)
constexpr int kSC = kStairCols;          // columns per thread, stride 32
constexpr int kSMaxWin = 16 + kSVy - 1;  // window rows at most (16 pixel rows)
constexpr int kSOffs = 4 + kSVx;  // origin x, origin y, pattern, staircase height, column offset per warp
constexpr int kSThreads = 32 * kSVx;

/// Floats of one frame's window (kSR + 3 rows of kStairPitch), rounded up to 128 bytes: the TMA writes
/// each window at a 128-byte-aligned address.
constexpr int stairWinSize(int rows) {
  return (kStairPitch * (rows + kSVy - 1) + 31) / 32 * 32;
}

/// Row offset of vy kK of the staircase with pattern kId (see stairOffsetsKernel), at compile time.
template <int kId, int kK>
struct StairRow {
  static constexpr int bits = kId < 8 ? kId : kId - 7;
  static constexpr int value =
      kId < 8
          ? ((kK > 0 ? (bits & 1) : 0) + (kK > 1 ? ((bits >> 1) & 1) : 0) + (kK > 2 ? ((bits >> 2) & 1) : 0))
          : ((kK <= 0 ? (bits & 1) : 0) + (kK <= 1 ? ((bits >> 1) & 1) : 0) +
             (kK <= 2 ? ((bits >> 2) & 1) : 0));
};
static_assert(kSVy == 4, "StairRow assumes staircases of 4 vy");
static_assert(kSMaxWin * kStairPitch / 4 <= 2 * kSThreads, "two copy slots per thread");

template <int kId, int kK, int kSR>
__device__ __forceinline__ void addStairRow(float (&acc)[kSVy][kSR][kSC], const float (&v)[kSR + 3][kSC]) {
  constexpr int kD = StairRow<kId, kK>::value;
#pragma unroll
  for (int r = 0; r < kSR; ++r) {
#pragma unroll
    for (int j = 0; j < kSC; ++j)
      acc[kK][r][j] += v[kD + r][j];
  }
}

/// The additions of one frame for staircase kId: first loads the rows below the tile this staircase
/// needs (its height, known here at compile time), then adds.
template <int kId, int kSR>
__device__ __forceinline__ void addStair(float (&acc)[kSVy][kSR][kSC], float (&v)[kSR + 3][kSC],
                                         const float* w) {
  constexpr int kA = StairRow<kId, 0>::value;
  constexpr int kB = StairRow<kId, kSVy - 1>::value;
  constexpr int kHeight = kA > kB ? kA : kB;
#pragma unroll
  for (int q = 0; q < kHeight; ++q) {
#pragma unroll
    for (int j = 0; j < kSC; ++j)
      v[kSR + q][j] = w[(kSR + q) * kStairPitch + 32 * j];
  }
  addStairRow<kId, 0, kSR>(acc, v);
  addStairRow<kId, 1, kSR>(acc, v);
  addStairRow<kId, 2, kSR>(acc, v);
  addStairRow<kId, 3, kSR>(acc, v);
}

/// The pipelined form of addStair: the additions run row by row of the window (each v row feeds the up
/// to 4 velocities that use it), and as soon as a tile row is no longer needed its register is refilled
/// from the next frame's window `wn`, so those loads overlap this frame's additions without extra
/// registers. Each accumulator still receives exactly one addition per frame, in frame order.
template <int kId, int kSR>
__device__ __forceinline__ void addStairPipe(float (&acc)[kSVy][kSR][kSC], float (&v)[kSR + 3][kSC],
                                             const float* w, const float* wn) {
  constexpr int kA = StairRow<kId, 0>::value;
  constexpr int kB = StairRow<kId, kSVy - 1>::value;
  constexpr int kHeight = kA > kB ? kA : kB;
  constexpr int kD[kSVy] = {StairRow<kId, 0>::value, StairRow<kId, 1>::value, StairRow<kId, 2>::value,
                            StairRow<kId, 3>::value};
#pragma unroll
  for (int q = 0; q < kHeight; ++q) {
#pragma unroll
    for (int j = 0; j < kSC; ++j)
      v[kSR + q][j] = w[(kSR + q) * kStairPitch + 32 * j];
  }
#pragma unroll
  for (int q = 0; q < kSR + kHeight; ++q) {
#pragma unroll
    for (int k = 0; k < kSVy; ++k) {
      const int r = q - kD[k];
      if (r < 0 || r >= kSR) continue;
#pragma unroll
      for (int j = 0; j < kSC; ++j)
        acc[k][r][j] += v[q][j];
    }
    if (q < kSR) {
#pragma unroll
      for (int j = 0; j < kSC; ++j)
        v[q][j] = wn[q * kStairPitch + 32 * j];
    }
  }
}

#define ST_STAIR_PIPE_CASE(c)            \
  case c:                                \
    addStairPipe<c, kSR>(acc, v, w, wn); \
    break;

#define ST_STAIR_CASE(c)         \
  case c:                        \
    addStair<c, kSR>(acc, v, w); \
    break;

#define ST_STAIR_SWITCH(CASE) \
  switch (pattern) {          \
    CASE(0)                   \
    CASE(1)                   \
    CASE(2)                   \
    CASE(3)                   \
    CASE(4)                   \
    CASE(5)                   \
    CASE(6)                   \
    CASE(7)                   \
    CASE(8)                   \
    CASE(9)                   \
    CASE(10)                  \
    CASE(11)                  \
    CASE(12)                  \
    CASE(13)                  \
    CASE(14)                  \
    default:                  \
      break;                  \
  }

/// The additions of one stage's `count` frames (windows `wins` + lane, offsets `offs`), frame by frame:
/// the tile rows are loaded, then one switch on the frame's staircase (uniform across the block).
template <int kSR>
__device__ __forceinline__ void stairStage(float (&acc)[kSVy][kSR][kSC], const float* wins, const int* offs,
                                           int count, int warp) {
  constexpr int winSize = stairWinSize(kSR);
  for (int i = 0; i < count; ++i) {
    const int* o = offs + i * kSOffs;
    const int pattern = o[2];
    const float* w = wins + i * winSize + o[4 + warp];
    float v[kSR + kSVy - 1][kSC];
#pragma unroll
    for (int r = 0; r < kSR + kSVy - 1; ++r) {
#pragma unroll
      for (int j = 0; j < kSC; ++j)
        v[r][j] = r < kSR ? w[r * kStairPitch + 32 * j] : 0.0f;  // rows below: loaded by the case
    }
    __builtin_assume(static_cast<unsigned>(pattern) < 15u);  // the host checked: a staircase, 0..14
    ST_STAIR_SWITCH(ST_STAIR_CASE)
  }
}

/// stairStage, software-pipelined: the tile rows of frame i + 1 are loaded during frame i's additions
/// (addStairPipe); the pattern and window of frame i + 1 are read before frame i's switch. The last frame
/// of the stage refills from its own window (the next stage's window is not ready yet).
template <int kSR>
__device__ __forceinline__ void stairStagePipe(float (&acc)[kSVy][kSR][kSC], const float* wins,
                                               const int* offs, int count, int warp) {
  constexpr int winSize = stairWinSize(kSR);
  if (count <= 0) return;
  float v[kSR + kSVy - 1][kSC];
  int pattern = offs[2];
  const float* w = wins + offs[4 + warp];
#pragma unroll
  for (int r = 0; r < kSR + kSVy - 1; ++r) {
#pragma unroll
    for (int j = 0; j < kSC; ++j)
      v[r][j] = r < kSR ? w[r * kStairPitch + 32 * j] : 0.0f;
  }
  for (int i = 0; i < count; ++i) {
    const int next = i + 1 < count ? i + 1 : i;
    const int* o = offs + next * kSOffs;
    const int nextPattern = o[2];
    const float* wn = wins + next * winSize + o[4 + warp];
    ST_STAIR_SWITCH(ST_STAIR_PIPE_CASE)
    pattern = nextPattern;
    w = wn;
  }
}

/// Words of one Float16 window (11 rows of kStairHalfPitch pairs), rounded up to 128 bytes for the TMA.
constexpr int stairHalfWinSize() {
  return (kStairHalfPitch * (8 + kSVy - 1) + 31) / 32 * 32;
}

template <int kId, int kK>
__device__ __forceinline__ void addStairHalfRow(__half2 (&h)[kSVy][8], const __half2 (&v)[8 + kSVy - 1]) {
  constexpr int kD = StairRow<kId, kK>::value;
#pragma unroll
  for (int r = 0; r < 8; ++r)
    h[kK][r] = __hadd2(h[kK][r], v[kD + r]);
}

/// addStair for Float16 frames (8 rows): each word holds columns (x, x + 32), one HADD2 adds both.
template <int kId>
__device__ __forceinline__ void addStairHalf(__half2 (&h)[kSVy][8], __half2 (&v)[8 + kSVy - 1],
                                             const __half2* w) {
  constexpr int kA = StairRow<kId, 0>::value;
  constexpr int kB = StairRow<kId, kSVy - 1>::value;
  constexpr int kHeight = kA > kB ? kA : kB;
#pragma unroll
  for (int q = 0; q < kHeight; ++q)
    v[8 + q] = w[(8 + q) * kStairHalfPitch];
  addStairHalfRow<kId, 0>(h, v);
  addStairHalfRow<kId, 1>(h, v);
  addStairHalfRow<kId, 2>(h, v);
  addStairHalfRow<kId, 3>(h, v);
}

#define ST_STAIR_HALF_CASE(c) \
  case c:                     \
    addStairHalf<c>(h, v, w); \
    break;

/// stairStage for Float16 frames (8 rows): the stage's frames summed in half pairs (at most
/// kStairHalfMaxStage frames: no overflow of values clamped to kStairHalfClamp), then added to the float
/// accumulators once.
__device__ __forceinline__ void stairStageHalf(float (&acc)[kSVy][8][kSC], const __half2* wins,
                                               const int* offs, int count, int warp) {
  static_assert(kSC == 2, "a half pair holds the thread's two columns");
  constexpr int winSize = stairHalfWinSize();
  __half2 h[kSVy][8];
#pragma unroll
  for (int k = 0; k < kSVy; ++k) {
#pragma unroll
    for (int r = 0; r < 8; ++r)
      h[k][r] = __float2half2_rn(0.0f);
  }
  // (Reading the next frame's pattern and offset before this frame's switch was slower: 1.14e13 vs 1.25e13
  // additions/s, H100, 2026-11-27, 16 frames per stage.)
  for (int i = 0; i < count; ++i) {
    const int* o = offs + i * kSOffs;
    const int pattern = o[2];
    const __half2* w = wins + i * winSize + o[4 + warp];
    __half2 v[8 + kSVy - 1];
#pragma unroll
    for (int r = 0; r < 8 + kSVy - 1; ++r)
      v[r] = r < 8 ? w[r * kStairHalfPitch] : __float2half2_rn(0.0f);  // rows below: loaded by the case
    // The host checked every pattern is a staircase (0..14): without this the switch compiled to a compare
    // tree of 2-3 branches before the jump table (H100, 2026-11-27: Float16 1.23e13 -> 1.36e13 additions/s,
    // Float32 1.03e13 -> 1.07e13 in the next run; no spills, 128 registers).
    __builtin_assume(static_cast<unsigned>(pattern) < 15u);
    ST_STAIR_SWITCH(ST_STAIR_HALF_CASE)
  }
#pragma unroll
  for (int k = 0; k < kSVy; ++k) {
#pragma unroll
    for (int r = 0; r < 8; ++r) {
      const float2 f = __half22float2(h[k][r]);
      acc[k][r][0] += f.x;
      acc[k][r][1] += f.y;
    }
  }
}

template <int kSR, bool kPipe>
__device__ __forceinline__ void stairStageAny(float (&acc)[kSVy][kSR][kSC], const float* wins,
                                              const int* offs, int count, int warp) {
  if (kPipe) {
    stairStagePipe<kSR>(acc, wins, offs, count, warp);
  } else {
    stairStage<kSR>(acc, wins, offs, count, warp);
  }
}

}  // namespace st::gpu::stair

// The stair kernel: the fast path of the exact IPSA search when neighbouring vy of the grid are at most
// 1 px apart at every frame (the paper's grid design). A block owns a 64 x 8 pixel tile (or 64 x 4) and 8
// consecutive vx (one per warp) x 4 consecutive vy. At one frame the 4 vy have row shifts that form a
// staircase (each step 0 or 1 px, all up or all down: one of 15 patterns), and all 4 share the column
// shift of the warp's vx. Each thread owns 2 columns (stride 32) x 8 rows: it loads the 8 + (staircase
// height) rows it needs into registers once per frame (conflict-free 4-byte shared loads at any column
// offset) and adds them into 4 velocities x 16 accumulators, the register of each addition fixed at compile
// time by a switch on the pattern, uniform across the block. One shared-memory value thus feeds up to 4
// additions and there is one branch per frame, not one per velocity. The window of a frame (11 rows x
// kStairPitch columns from a 16-byte-aligned origin, zeros outside the frame) is copied once per frame by
// the tensor memory accelerator (one instruction, completion on an mbarrier; 16-byte cp.async when the
// driver cannot make a tensor map) and serves all 32 velocities of the block. The per-frame offsets table
// is copied one stage ahead. Per cell the additions run frame by frame, as in the other kernels (same
// sums, bit for bit).
#include <cuda.h>
#include <cudaTypedefs.h>
#include <cuda_runtime.h>

#include "cuda_check.hpp"
#include "kernel_params.hpp"
#include "search_device.cuh"
#include "stair_stage.cuh"

namespace st::gpu {
namespace {

using namespace stair;  // NOLINT: the stair kernel's constants and per-frame bodies

__device__ __forceinline__ int floor4s(int v) {
  return v - (((v % 4) + 4) % 4);
}

__global__ void stairOffsetsKernel(SearchLaunch p, int* out, int tileCount) {
  const long long i = blockIdx.x * static_cast<long long>(blockDim.x) + threadIdx.x;
  if (i >= static_cast<long long>(tileCount) * p.frameCount) return;
  const int tile = static_cast<int>(i / p.frameCount);
  const int n = static_cast<int>(i % p.frameCount);
  const int tilesX = (p.nvx + kSVx - 1) / kSVx;
  const int ixBase = (tile % tilesX) * kSVx;
  const int iyBase = p.iy0 + (tile / tilesX) * kSVy;
  int sx[kSVx];
  int ox = 1 << 30;
  for (int k = 0; k < kSVx; ++k) {
    sx[k] = p.shiftX[static_cast<long long>(min(ixBase + k, p.nvx - 1)) * p.frameCount + n];
    ox = min(ox, sx[k]);
  }
  ox = floor4s(ox);
  int sy[kSVy];
  int oy = 1 << 30;
  for (int k = 0; k < kSVy; ++k) {
    sy[k] = p.shiftY[static_cast<long long>(min(iyBase + k, p.iy1 - 1)) * p.frameCount + n];
    oy = min(oy, sy[k]);
  }
  // Pattern: rising staircase (steps a, b, c in {0, 1}) -> a + 2b + 4c; falling -> 7 + a + 2b + 4c.
  const bool rising = sy[kSVy - 1] >= sy[0];
  int id = 0;
  for (int k = 0; k < kSVy - 1; ++k) {
    const int step = rising ? sy[k + 1] - sy[k] : sy[k] - sy[k + 1];
    id += step << k;
  }
  if (!rising) id += 7;
  int* o = out + i * kSOffs;
  o[0] = ox;
  o[1] = oy;
  o[2] = id;
  o[3] = max(max(sy[0], sy[kSVy - 1]) - oy, 0);
  for (int k = 0; k < kSVx; ++k)
    o[4 + k] = sx[k] - ox;
}

/// Issues the asynchronous copy of the offsets of frames [n0, n0 + count) into `offs`.
__device__ void copyStairOffsets(const SearchLaunch& p, int* offs, int n0, int count, int tile) {
  const int* to = p.tileOffsets + (static_cast<long long>(tile) * p.frameCount + n0) * kSOffs;
  for (int e = threadIdx.x; e < count * kSOffs; e += kSThreads) {
    const unsigned d = static_cast<unsigned>(__cvta_generic_to_shared(offs + e));
    asm volatile("cp.async.ca.shared.global [%0], [%1], 4;\n" ::"r"(d), "l"(to + e));
  }
}

/// The 16-byte chunks of a window a thread copies: up to kSWin x kStairPitch / 4 <= 2 kSThreads chunks, so
/// two slots, each packed as (row << 16) | column, or -1 when unused. Computed once per block.
template <bool kHalf>
__device__ __forceinline__ int stairSlot(const SearchLaunch& p, int e, int winRows) {
  const int chunksPerRow = (kHalf ? p.pitch - 32 : p.pitch) / 4;  // copied; shared stride kStairPitch
  if (e >= winRows * chunksPerRow) return -1;
  const int r = e / chunksPerRow;
  return (r << 16) | ((e - r * chunksPerRow) * 4);
}

template <bool kHalf>
__device__ __forceinline__ void copyStairChunk(const SearchLaunch& p, float* w, const float* frame, int slot,
                                               int gx0, int gy0) {
  constexpr int kPitch = kHalf ? kStairHalfPitch : kStairPitch;
  const int rowWords = kHalf ? p.width + kStairHalfPad : p.width;  // half pairs: kStairHalfPad on the left
  const int r = slot >> 16;
  const int c = slot & 0xFFFF;
  const int gy = gy0 + r;
  const int gx = gx0 + c + (kHalf ? kStairHalfPad : 0);
  const bool in = gy >= 0 && gy < p.height && gx >= 0 && gx < rowWords;  // both % 4 == 0: all 4 or none
  cpAsync16(w + r * kPitch + c, in ? frame + static_cast<long long>(gy) * rowWords + gx : frame, in);
}

/// Issues the asynchronous copies of the windows of frames [n0, n0 + count) into `win`, their origins read
/// from `offs` (already in shared memory: no wait on global memory here).
template <bool kHalf>
__device__ void copyStairWindows(const SearchLaunch& p, float* win, const int* offs, int n0, int count,
                                 int x0, int y0, int slot0, int slot1, int winSize) {
  // Float16: the half pairs, copied as 4-byte words like floats.
  const float* frames = kHalf ? reinterpret_cast<const float*>(p.framesHalf) : p.frames;
  for (int i = 0; i < count; ++i) {
    const int gx0 = x0 + offs[i * kSOffs];
    const int gy0 = y0 + offs[i * kSOffs + 1];
    const float* frame = frames + static_cast<long long>(n0 + i - p.frameBase) *
                                      (p.width + (kHalf ? kStairHalfPad : 0)) * p.height;
    float* w = win + i * winSize;
    if (slot0 >= 0) copyStairChunk<kHalf>(p, w, frame, slot0, gx0, gy0);
    if (slot1 >= 0) copyStairChunk<kHalf>(p, w, frame, slot1, gx0, gy0);
  }
}

__device__ __forceinline__ void cpAsyncWaitAll() {
  asm volatile("cp.async.wait_group 0;\n" ::);
}

__device__ __forceinline__ unsigned smemAddr(const void* p) {
  return static_cast<unsigned>(__cvta_generic_to_shared(p));
}

/// Thread 0 starts the tensor-memory-accelerator copies of the windows of frames [n0, n0 + count) (one
/// instruction per frame; rows and columns outside the frame arrive as zeros) and tells `bar` how many
/// bytes to expect.
__device__ void tmaStairWindows(const CUtensorMap* map, const SearchLaunch& p, float* win, const int* offs,
                                int n0, int count, int x0, int y0, unsigned long long* bar, int winSize,
                                int boxFloats) {
  const unsigned b = smemAddr(bar);
  const unsigned bytes = static_cast<unsigned>(count * boxFloats * sizeof(float));  // the boxes, no padding
  asm volatile("mbarrier.arrive.expect_tx.shared::cta.b64 _, [%0], %1;\n" ::"r"(b), "r"(bytes) : "memory");
  const unsigned long long m = reinterpret_cast<unsigned long long>(map);
  for (int i = 0; i < count; ++i) {
    const int gx = x0 + offs[i * kSOffs] + (p.framesHalf ? kStairHalfPad : 0);
    const int gy = y0 + offs[i * kSOffs + 1];
    const int gz = n0 + i - p.frameBase;
    asm volatile(
        "cp.async.bulk.tensor.3d.shared::cluster.global.tile.mbarrier::complete_tx::bytes [%0], [%1, {%2, "
        "%3, %4}], [%5];\n" ::"r"(smemAddr(win + i * winSize)),
        "l"(m), "r"(gx), "r"(gy), "r"(gz), "r"(b)
        : "memory");
  }
}

/// Two barriers (one per window buffer), one arrival each (the expect_tx) plus the bytes.
__device__ void initStairBarriers(unsigned long long* bars) {
  for (int i = 0; i < 2; ++i)
    asm volatile("mbarrier.init.shared::cta.b64 [%0], 1;\n" ::"r"(smemAddr(bars + i)) : "memory");
  asm volatile("fence.mbarrier_init.release.cluster;\n" ::: "memory");
}

__device__ __forceinline__ void mbarrierWait(unsigned long long* bar, int parity) {
  unsigned done = 0;
  do {
    asm volatile(
        "{\n .reg .pred q;\n mbarrier.try_wait.parity.shared::cta.b64 q, [%1], %2;\n selp.u32 %0, 1, 0, "
        "q;\n}\n"
        : "=r"(done)
        : "r"(smemAddr(bar)), "r"(parity)
        : "memory");
  } while (!done);
}

/// The end of a launch for one thread's 4 vy x kSR x kSC cells: partial sums stored, or cells scored and
/// each velocity's best key reduced over the warp into the map.
template <int kSR, bool kHalf, class PartialAt, class CellOk>
__device__ __forceinline__ void finishStairTile(const SearchLaunch& p, const float (&acc)[kSVy][kSR][kSC],
                                                PartialAt partialAt, CellOk cellOk, int ix, int iyBase,
                                                int x0, int y0, int lane) {
#pragma unroll
  for (int k = 0; k < kSVy; ++k) {
    const int iy = iyBase + k;
    if (ix >= p.nvx || iy >= p.iy1) continue;  // uniform across the warp
    unsigned long long best = 0ull;
#pragma unroll
    for (int r = 0; r < kSR; ++r) {
#pragma unroll
      for (int j = 0; j < kSC; ++j) {
        if (!cellOk(k, r, j)) continue;
        if (!p.finalize) {  // not finishCell: 120 instructions more here, 1.02e13 vs 1.05e13 (separate runs)
          p.partial[partialAt(k, r, j)] = acc[k][r][j];
          continue;
        }
        const int x = x0 + lane + 32 * j;
        const int y = y0 + r;
        const int nIn = cellFrames(p, ix, x, iy, y);
        const float sum = kHalf ? acc[k][r][j] * p.halfInvScale : acc[k][r][j];  // exact: a power of 2
        const unsigned long long key = scoreCell(p, sum, nIn, x, y, ix, iy);
        best = key > best ? key : best;
      }
    }
    if (p.finalize) {
      best = warpMax(best);
      if (lane == 0 && best != 0ull) atomicMax(p.mapKeys + static_cast<long long>(iy) * p.nvx + ix, best);
    }
  }
}

/// kSR pixel rows per thread (and block): 8 (two blocks per SM) or 4 (four blocks per SM: more warps to
/// hide latencies, fewer additions per shared-memory load).
/// kTma: windows copied by the tensor memory accelerator (`map`, one instruction per frame) instead of
/// per-thread 16-byte cp.async.
/// kHalf: Float16 frames (p.framesHalf, 8 rows only): windows of half pairs, stairStageHalf.
template <int kSR, bool kTma, bool kPipe, bool kHalf = false>
__global__ void __launch_bounds__(kSThreads, kSR == 4 ? 4 : 2)
    stairSearchKernel(SearchLaunch p, const __grid_constant__ CUtensorMap map) {
  static_assert(!kHalf || (kSR == 8 && !kPipe), "Float16: 8 rows, plain frame loop");
  constexpr int kSWin = kSR + kSVy - 1;
  extern __shared__ __align__(128) float smem[];
  __shared__ __align__(8) unsigned long long bars[2];  // TMA: windows of buffer 0 / 1 landed
  if (kTma && threadIdx.x == 0) initStairBarriers(bars);
  const int lane = threadIdx.x & 31;
  const int warp = threadIdx.x >> 5;
  const int tile = blockIdx.x;  // velocity tiles vary fastest: resident blocks share pixel tiles in L2
  const int x0 = blockIdx.y * 32 * kSC;
  const int y0 = blockIdx.z * kSR;
  const int tilesX = (p.nvx + kSVx - 1) / kSVx;
  const int ix = (tile % tilesX) * kSVx + warp;
  const int iyBase = p.iy0 + (tile / tilesX) * kSVy;
  const int fs = p.framesPerStage;
  constexpr int winSize = kHalf ? stairHalfWinSize() : stairWinSize(kSR);
  float* wins = smem;
  int* offs = reinterpret_cast<int*>(smem + 2 * fs * winSize);
  const long long plane = static_cast<long long>(p.width) * p.height;
  auto partialAt = [&](int k, int r, int j) {
    return (static_cast<long long>(iyBase + k - p.iy0) * p.nvx + ix) * plane +
           static_cast<long long>(y0 + r) * p.width + x0 + lane + 32 * j;
  };
  auto cellOk = [&](int k, int r, int j) {
    return ix < p.nvx && iyBase + k < p.iy1 && x0 + lane + 32 * j < p.width && y0 + r < p.height;
  };

  float acc[kSVy][kSR][kSC];
#pragma unroll
  for (int k = 0; k < kSVy; ++k) {
#pragma unroll
    for (int r = 0; r < kSR; ++r) {
#pragma unroll
      for (int j = 0; j < kSC; ++j)
        acc[k][r][j] = (p.loadPartial && cellOk(k, r, j)) ? p.partial[partialAt(k, r, j)] : 0.0f;
    }
  }

  const int frames = p.f1 - p.f0;
  const int stages = (frames + fs - 1) / fs;
  auto stageOffs = [&](int st) { return offs + (st % 3) * fs * kSOffs; };
  auto stageCount = [&](int st) { return min(fs, frames - st * fs); };
  // Pipeline: the copies issued at the start of stage s - 1 are the windows of stage s and the offsets of
  // stage s + 1, so the window copies of stage s + 1 start from offsets already in shared memory (3 offset
  // buffers, 2 window buffers). TMA windows complete on bars[buffer], the rest on cp.async groups.
  const int slot0 = kTma ? -1 : stairSlot<kHalf>(p, threadIdx.x, kSWin);
  const int slot1 = kTma ? -1 : stairSlot<kHalf>(p, threadIdx.x + kSThreads, kSWin);
  auto issueStage = [&](int st) {  // windows of stage st, offsets of stage st + 1
    float* w = wins + (st & 1) * fs * winSize;
    if (kTma) {
      if (threadIdx.x == 0)
        tmaStairWindows(&map, p, w, stageOffs(st), p.f0 + st * fs, stageCount(st), x0, y0, &bars[st & 1],
                        winSize, (kHalf ? kStairHalfPitch : kStairPitch) * kSWin);
    } else {
      copyStairWindows<kHalf>(p, w, stageOffs(st), p.f0 + st * fs, stageCount(st), x0, y0, slot0, slot1,
                              winSize);
    }
    if (st + 1 < stages)
      copyStairOffsets(p, stageOffs(st + 1), p.f0 + (st + 1) * fs, stageCount(st + 1), tile);
    cpAsyncCommit();
  };
  if (stages > 0) {
    copyStairOffsets(p, stageOffs(0), p.f0, stageCount(0), tile);
    cpAsyncCommit();
    cpAsyncWaitAll();
    __syncthreads();
    issueStage(0);
  }
  for (int s = 0; s < stages; ++s) {
    cpAsyncWaitAll();
    __syncthreads();  // stage s landed everywhere (but TMA windows), and stage s - 1 is no longer read
    if (s + 1 < stages) issueStage(s + 1);
    if (kTma) mbarrierWait(&bars[s & 1], (s >> 1) & 1);  // the k-th use of a buffer completes phase k
    if constexpr (kHalf) {
      stairStageHalf(acc, reinterpret_cast<const __half2*>(wins + (s & 1) * fs * winSize) + lane,
                     stageOffs(s), stageCount(s), warp);
    } else {
      stairStageAny<kSR, kPipe>(acc, wins + (s & 1) * fs * winSize + lane, stageOffs(s), stageCount(s), warp);
    }
  }

  finishStairTile<kSR, kHalf>(p, acc, partialAt, cellOk, ix, iyBase, x0, y0, lane);
}

/// launchHalfPairs: one thread per output word (rows of width + kStairHalfPad words).
__global__ void halfPairsKernel(const float* frames, unsigned* out, int width, long long total, float scale) {
  const long long i = blockIdx.x * static_cast<long long>(blockDim.x) + threadIdx.x;
  if (i >= total) return;
  const int rowWords = width + kStairHalfPad;
  const long long row = i / rowWords;  // frame * height + y
  const int x = static_cast<int>(i - row * rowWords) - kStairHalfPad;
  const float* f = frames + row * width;
  auto conv = [&](float v) {
    return __float2half_rn(fminf(fmaxf(v * scale, -kStairHalfClamp), kStairHalfClamp));
  };
  const __half lo = x >= 0 ? conv(f[x]) : __float2half_rn(0.0f);
  const __half hi = x + 32 < width ? conv(f[x + 32]) : __float2half_rn(0.0f);
  const __half2 pair = __halves2half2(lo, hi);
  out[i] = *reinterpret_cast<const unsigned*>(&pair);
}

}  // namespace

void launchHalfPairs(const float* frames, unsigned* out, int width, int height, int f0, int f1, float scale,
                     cudaStream_t stream) {
  const long long plane = static_cast<long long>(width) * height;
  const long long halfPlane = static_cast<long long>(width + kStairHalfPad) * height;
  const long long total = halfPlane * (f1 - f0);
  if (total <= 0) return;
  halfPairsKernel<<<static_cast<unsigned>((total + 255) / 256), 256, 0, stream>>>(
      frames + plane * f0, out + halfPlane * f0, width, total, scale);
  checkLaunch("halfPairsKernel");
}

std::size_t stairSharedBytes(int framesPerStage, int rows) {
  return static_cast<std::size_t>(framesPerStage) *
         (2 * static_cast<std::size_t>(stairWinSize(rows)) * sizeof(float) + 3 * kSOffs * sizeof(int));
}

std::size_t stairHalfSharedBytes(int framesPerStage) {
  return static_cast<std::size_t>(framesPerStage) *
         (2 * static_cast<std::size_t>(stairHalfWinSize()) * sizeof(float) + 3 * kSOffs * sizeof(int));
}

template <int kSR, bool kTma, bool kPipe, bool kHalf = false>
void setStairShared(int bytes) {
  ST_CUDA_CHECK(cudaFuncSetAttribute(stairSearchKernel<kSR, kTma, kPipe, kHalf>,
                                     cudaFuncAttributeMaxDynamicSharedMemorySize, bytes));
}

void configureStairKernel(std::size_t sharedBytes, int rows) {
  const int bytes = static_cast<int>(sharedBytes);
  if (rows == 4) {
    setStairShared<4, false, false>(bytes);
    setStairShared<4, true, false>(bytes);
  } else {
    setStairShared<8, false, false>(bytes);
    setStairShared<8, true, false>(bytes);
    setStairShared<8, true, true>(bytes);
    setStairShared<8, true, false, true>(bytes);
    setStairShared<8, false, false, true>(bytes);
  }
}

namespace {

/// cuTensorMapEncodeTiled from the driver (no link against libcuda), or null.
PFN_cuTensorMapEncodeTiled_v12000 tensorMapEncoder() {
  static const PFN_cuTensorMapEncodeTiled_v12000 fn = [] {
    void* f = nullptr;
    cudaDriverEntryPointQueryResult q{};
    if (cudaGetDriverEntryPointByVersion("cuTensorMapEncodeTiled", &f, 12000, cudaEnableDefault, &q) !=
            cudaSuccess ||
        q != cudaDriverEntryPointSuccess) {
      cudaGetLastError();
      return static_cast<PFN_cuTensorMapEncodeTiled_v12000>(nullptr);
    }
    return reinterpret_cast<PFN_cuTensorMapEncodeTiled_v12000>(f);
  }();
  return fn;
}

/// The tensor map of the resident frames [frameBase, f1) with a box of one window; false when the driver
/// cannot make one (the kernel then copies with cp.async).
bool makeWindowMap(const SearchLaunch& p, int winRows, CUtensorMap& map) {
  const bool half = p.framesHalf != nullptr;  // 4-byte pairs, a narrower box
  const auto encode = tensorMapEncoder();
  if (encode == nullptr) return false;
  const cuuint64_t rowWords = static_cast<cuuint64_t>(p.width) + (half ? kStairHalfPad : 0);
  const cuuint64_t dims[3] = {rowWords, static_cast<cuuint64_t>(p.height),
                              static_cast<cuuint64_t>(p.f1 - p.frameBase)};
  const cuuint64_t strides[2] = {rowWords * sizeof(float), rowWords * p.height * sizeof(float)};
  const cuuint32_t box[3] = {static_cast<cuuint32_t>(half ? kStairHalfPitch : kStairPitch),
                             static_cast<cuuint32_t>(winRows), 1};
  const cuuint32_t elementStrides[3] = {1, 1, 1};
  void* base = half ? static_cast<void*>(const_cast<unsigned*>(p.framesHalf))
                    : static_cast<void*>(const_cast<float*>(p.frames));
  return encode(&map, CU_TENSOR_MAP_DATA_TYPE_FLOAT32, 3, base, dims, strides, box, elementStrides,
                CU_TENSOR_MAP_INTERLEAVE_NONE, CU_TENSOR_MAP_SWIZZLE_NONE, CU_TENSOR_MAP_L2_PROMOTION_L2_128B,
                CU_TENSOR_MAP_FLOAT_OOB_FILL_NONE) == CUDA_SUCCESS;
}

}  // namespace

int stairTileCount(int nvx, int rows) {
  return ((nvx + kSVx - 1) / kSVx) * ((rows + kSVy - 1) / kSVy);
}

std::size_t stairOffsetInts() {
  return kSOffs;
}

void launchStairOffsets(const SearchLaunch& p, int* tileOffsets, int tileCount, cudaStream_t stream) {
  const long long total = static_cast<long long>(tileCount) * p.frameCount;
  stairOffsetsKernel<<<static_cast<int>((total + 255) / 256), 256, 0, stream>>>(p, tileOffsets, tileCount);
  checkLaunch("stairOffsetsKernel");
}

void launchStairSearch(const SearchLaunch& p, cudaStream_t stream) {
  const int rows = p.stairRows;
  const dim3 grid(stairTileCount(p.nvx, p.iy1 - p.iy0), (p.width + 32 * kSC - 1) / (32 * kSC),
                  (p.height + rows - 1) / rows);
  const bool half = p.framesHalf != nullptr && rows == 8;
  const std::size_t shared =
      half ? stairHalfSharedBytes(p.framesPerStage) : stairSharedBytes(p.framesPerStage, rows);
  CUtensorMap map{};
  const bool tma = p.stairTma && p.width % 4 == 0 && makeWindowMap(p, rows + kSVy - 1, map);
  if (half) {
    if (tma) {
      stairSearchKernel<8, true, false, true><<<grid, kSThreads, shared, stream>>>(p, map);
    } else {
      stairSearchKernel<8, false, false, true><<<grid, kSThreads, shared, stream>>>(p, map);
    }
  } else if (rows == 4) {
    if (tma) {
      stairSearchKernel<4, true, false><<<grid, kSThreads, shared, stream>>>(p, map);
    } else {
      stairSearchKernel<4, false, false><<<grid, kSThreads, shared, stream>>>(p, map);
    }
  } else if (tma && p.stairPipe) {
    stairSearchKernel<8, true, true><<<grid, kSThreads, shared, stream>>>(p, map);
  } else if (tma) {
    stairSearchKernel<8, true, false><<<grid, kSThreads, shared, stream>>>(p, map);
  } else {
    stairSearchKernel<8, false, false><<<grid, kSThreads, shared, stream>>>(p, map);
  }
  checkLaunch("stairSearchKernel");
}

}  // namespace st::gpu

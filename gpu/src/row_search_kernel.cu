// The row kernel: the fast path of the exact IPSA search when groups of 8 neighbouring velocities of one
// grid row (same vy, so the same row shift at every frame) stay within a few pixels of each other in x.
// A block owns a 128-column pixel tile and G groups of 8 consecutive vx of one vy (G = 8, 4, 2 or 1; its
// 8 warps are G groups x 8/G row pairs). Each frame's input window (the tile's rows x the columns all G
// groups need, 16-byte aligned) is copied once into shared memory with 16-byte cp.async and serves 8G
// velocities, so few bytes move per addition. Each thread owns 4 consecutive columns in 2 rows: it loads
// its row segment (16 columns) into registers once per frame with 16-byte loads, and each of its 8
// velocities adds the segment shifted by its own x offset (a warp-uniform switch), so one shared-memory
// value serves up to 8 velocities. Per cell the additions run frame by frame, as in the other kernels.
#include <cuda_runtime.h>

#include "cuda_check.hpp"
#include "kernel_params.hpp"
#include "search_device.cuh"

namespace st::gpu {
namespace {

constexpr int kRV = kRowVelocities;
constexpr int kRCols = 4;
constexpr int kRRows = 2;
constexpr int kRTileW = 32 * kRCols;
constexpr int kRSeg = 16;  // floats of one thread-row segment
constexpr int kRMaxGroups = 8;
constexpr int kGOffs =
    2 + 3 * kRMaxGroups;  // origin x, row shift, then per group: base, 2 packed offset words
static_assert(kRowMaxOffset + kRCols <= kRSeg, "segment must hold the largest offset");

__device__ __forceinline__ int floor4(int v) {
  return v - (((v % 4) + 4) % 4);
}

__global__ void rowOffsetsKernel(SearchLaunch p, int* out, int tileCount) {
  const long long i = blockIdx.x * static_cast<long long>(blockDim.x) + threadIdx.x;
  if (i >= static_cast<long long>(tileCount) * p.frameCount) return;
  const int tile = static_cast<int>(i / p.frameCount);
  const int n = static_cast<int>(i % p.frameCount);
  const int perTile = kRV * p.groups;
  const int tilesX = (p.nvx + perTile - 1) / perTile;
  const int ixBase = (tile % tilesX) * perTile;
  const int iy = p.iy0 + tile / tilesX;
  int* o = out + i * kGOffs;
  int origin = 1 << 30;
  for (int k = 0; k < perTile; ++k) {
    origin = min(origin, p.shiftX[static_cast<long long>(min(ixBase + k, p.nvx - 1)) * p.frameCount + n]);
  }
  origin = floor4(origin);
  o[0] = origin;
  o[1] = p.shiftY[static_cast<long long>(iy) * p.frameCount + n];
  for (int g = 0; g < p.groups; ++g) {
    int sx[kRV];
    int gmin = 1 << 30;
    for (int k = 0; k < kRV; ++k) {
      sx[k] = p.shiftX[static_cast<long long>(min(ixBase + kRV * g + k, p.nvx - 1)) * p.frameCount + n];
      gmin = min(gmin, sx[k]);
    }
    const int base = floor4(gmin);
    unsigned packed[2] = {0u, 0u};
    for (int k = 0; k < kRV; ++k)
      packed[k / 4] |= static_cast<unsigned>(sx[k] - base) << (8 * (k % 4));
    o[2 + 3 * g] = base - origin;
    o[3 + 3 * g] = static_cast<int>(packed[0]);
    o[4 + 3 * g] = static_cast<int>(packed[1]);
  }
}

__device__ void issueRowStage(const SearchLaunch& p, float* win, int* offs, int n0, int count, int tile,
                              int x0, int y0) {
  const int chunksPerRow = p.pitch / 4;
  const int winSize = p.pitch * p.winRows;
  for (int i = 0; i < count; ++i) {
    const int n = n0 + i;
    const int* to = p.tileOffsets + (static_cast<long long>(tile) * p.frameCount + n) * kGOffs;
    if (threadIdx.x < kGOffs) offs[i * kGOffs + threadIdx.x] = to[threadIdx.x];
    const int gx0 = x0 + to[0];
    const int gy0 = y0 + to[1];
    const float* frame = p.frames + static_cast<long long>(n - p.frameBase) * p.width * p.height;
    float* w = win + i * winSize;
    for (int e = threadIdx.x; e < p.winRows * chunksPerRow; e += kThreads) {
      const int r = e / chunksPerRow;
      const int c = (e - r * chunksPerRow) * 4;
      const int gy = gy0 + r;
      const int gx = gx0 + c;
      const bool in = gy >= 0 && gy < p.height && gx >= 0 && gx < p.width;  // width % 4 == 0: all 4 or none
      cpAsync16(w + r * p.pitch + c, in ? frame + static_cast<long long>(gy) * p.width + gx : frame, in);
    }
  }
  cpAsyncCommit();
}

#define ST_ROW_CASE(c)                                                                    \
  case c:                                                                                 \
    _Pragma("unroll") for (int r = 0; r < kRRows; ++r) {                                  \
      _Pragma("unroll") for (int j = 0; j < kRCols; ++j) acc[k][r][j] += seg[r][(c) + j]; \
    }                                                                                     \
    break;

__global__ void __launch_bounds__(kThreads, 2) rowSearchKernel(SearchLaunch p) {
  extern __shared__ float smem[];
  const int lane = threadIdx.x & 31;
  const int warp = threadIdx.x >> 5;
  const int g = warp % p.groups;        // this warp's velocity group
  const int rowPair = warp / p.groups;  // and its two rows
  const int perTile = kRV * p.groups;
  // Velocity tiles vary fastest: blocks resident together share pixel tiles, so frame windows hit in L2.
  const int tile = blockIdx.x;
  const int x0 = blockIdx.y * kRTileW;
  const int y0 = blockIdx.z * p.winRows;
  const int tilesX = (p.nvx + perTile - 1) / perTile;
  const int ix0 = (tile % tilesX) * perTile + kRV * g;
  const int iy = p.iy0 + tile / tilesX;
  const int fs = p.framesPerStage;
  const int winSize = p.pitch * p.winRows;
  float* wins = smem;
  int* offs = reinterpret_cast<int*>(smem + 2 * fs * winSize);
  __shared__ unsigned long long blockKeys[kRV * kRMaxGroups];
  if (threadIdx.x < kRV * kRMaxGroups) blockKeys[threadIdx.x] = 0ull;
  const long long plane = static_cast<long long>(p.width) * p.height;
  const int xBase = x0 + lane * kRCols;
  const int yBase = y0 + 2 * rowPair;
  auto partialAt = [&](int k, int r, int j) {
    return (static_cast<long long>(iy - p.iy0) * p.nvx + ix0 + k) * plane +
           static_cast<long long>(yBase + r) * p.width + xBase + j;
  };
  auto inImage = [&](int r, int j) { return xBase + j < p.width && yBase + r < p.height; };

  float acc[kRV][kRRows][kRCols];
#pragma unroll
  for (int k = 0; k < kRV; ++k) {
#pragma unroll
    for (int r = 0; r < kRRows; ++r) {
#pragma unroll
      for (int j = 0; j < kRCols; ++j) {
        acc[k][r][j] =
            (p.loadPartial && ix0 + k < p.nvx && inImage(r, j)) ? p.partial[partialAt(k, r, j)] : 0.0f;
      }
    }
  }

  const int frames = p.f1 - p.f0;
  const int stages = (frames + fs - 1) / fs;
  issueRowStage(p, wins, offs, p.f0, min(fs, frames), tile, x0, y0);
  for (int s = 0; s < stages; ++s) {
    const int buf = s & 1;
    if (s + 1 < stages) {
      const int n0 = p.f0 + (s + 1) * fs;
      issueRowStage(p, wins + (buf ^ 1) * fs * winSize, offs + (buf ^ 1) * fs * kGOffs, n0,
                    min(fs, p.f1 - n0), tile, x0, y0);
    } else {
      cpAsyncCommit();
    }
    cpAsyncWaitOne();
    __syncthreads();
    const int count = min(fs, frames - s * fs);
    for (int i = 0; i < count; ++i) {
      const int* o = offs + (buf * fs + i) * kGOffs;
      const float* w = wins + (buf * fs + i) * winSize + 2 * rowPair * p.pitch + o[2 + 3 * g] + lane * kRCols;
      const unsigned pk[2] = {static_cast<unsigned>(o[3 + 3 * g]), static_cast<unsigned>(o[4 + 3 * g])};
      // Offsets grow (or shrink) monotonically with vx: the largest is at one end.
      const int dMax = max(static_cast<int>(pk[0] & 0xFFu), static_cast<int>(pk[1] >> 24));
      float seg[kRRows][kRSeg];
#pragma unroll
      for (int r = 0; r < kRRows; ++r) {
#pragma unroll
        for (int q = 0; q < kRSeg / 4; ++q) {
          if (4 * q <= dMax + kRCols - 1) {  // warp-uniform: only the vectors some velocity reads
            const float4 v = *reinterpret_cast<const float4*>(w + r * p.pitch + 4 * q);
            seg[r][4 * q] = v.x;
            seg[r][4 * q + 1] = v.y;
            seg[r][4 * q + 2] = v.z;
            seg[r][4 * q + 3] = v.w;
          }
        }
      }
#pragma unroll
      for (int k = 0; k < kRV; ++k) {
        switch ((pk[k / 4] >> (8 * (k % 4))) & 0xFFu) {  // uniform across the warp
          ST_ROW_CASE(0)
          ST_ROW_CASE(1)
          ST_ROW_CASE(2)
          ST_ROW_CASE(3)
          ST_ROW_CASE(4)
          ST_ROW_CASE(5)
          ST_ROW_CASE(6)
          ST_ROW_CASE(7)
          ST_ROW_CASE(8)
          ST_ROW_CASE(9)
          ST_ROW_CASE(10)
          ST_ROW_CASE(11)
          ST_ROW_CASE(12)
          default:
            break;
        }
      }
    }
    __syncthreads();
  }

#pragma unroll
  for (int k = 0; k < kRV; ++k) {
    const int ix = ix0 + k;
    if (ix >= p.nvx) continue;  // uniform across the warp
    unsigned long long best = 0ull;
#pragma unroll
    for (int r = 0; r < kRRows; ++r) {
#pragma unroll
      for (int j = 0; j < kRCols; ++j) {
        if (!inImage(r, j)) continue;
        const unsigned long long key =
            finishCell(p, acc[k][r][j], partialAt(k, r, j), xBase + j, yBase + r, ix, iy);
        best = key > best ? key : best;
      }
    }
    if (p.finalize) {
      best = warpMax(best);
      if (lane == 0 && best != 0ull) atomicMax(&blockKeys[kRV * g + k], best);
    }
  }
  if (!p.finalize) return;
  __syncthreads();
  const int ixTile = (tile % tilesX) * perTile + static_cast<int>(threadIdx.x);
  if (static_cast<int>(threadIdx.x) < perTile && ixTile < p.nvx && blockKeys[threadIdx.x] != 0ull) {
    atomicMax(p.mapKeys + static_cast<long long>(iy) * p.nvx + ixTile, blockKeys[threadIdx.x]);
  }
}

}  // namespace

std::size_t rowSharedBytes(int pitch, int winRows, int framesPerStage) {
  return static_cast<std::size_t>(2) * framesPerStage *
         (static_cast<std::size_t>(pitch) * winRows * sizeof(float) + kGOffs * sizeof(int));
}

void configureRowKernel(std::size_t sharedBytes) {
  ST_CUDA_CHECK(cudaFuncSetAttribute(rowSearchKernel, cudaFuncAttributeMaxDynamicSharedMemorySize,
                                     static_cast<int>(sharedBytes)));
}

int rowTileCount(int nvx, int rows, int groups) {
  const int perTile = kRV * groups;
  return ((nvx + perTile - 1) / perTile) * rows;
}

std::size_t rowOffsetInts() {
  return kGOffs;
}

void launchRowOffsets(const SearchLaunch& p, int* tileOffsets, int tileCount, cudaStream_t stream) {
  const long long total = static_cast<long long>(tileCount) * p.frameCount;
  rowOffsetsKernel<<<static_cast<int>((total + 255) / 256), 256, 0, stream>>>(p, tileOffsets, tileCount);
  checkLaunch("rowOffsetsKernel");
}

void launchRowSearch(const SearchLaunch& p, cudaStream_t stream) {
  const dim3 grid(rowTileCount(p.nvx, p.iy1 - p.iy0, p.groups), (p.width + kRTileW - 1) / kRTileW,
                  (p.height + p.winRows - 1) / p.winRows);
  rowSearchKernel<<<grid, kThreads, rowSharedBytes(p.pitch, p.winRows, p.framesPerStage), stream>>>(p);
  checkLaunch("rowSearchKernel");
}

}  // namespace st::gpu

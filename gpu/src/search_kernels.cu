// The exact IPSA velocity search on the GPU (ARCHITECTURE.md "IPSA"; paper section 4):
//   S(x,y,v) = sum_n F_n(x + sx_n(v), y + sy_n(v)),  sx_n = round(vx dt_n), sy_n = round(vy dt_n).
// Tiled kernel: a block owns an output tile (kTileW x kTileH pixels) and kVelPerBlock velocities. For each
// frame it copies, once, the input window the tile needs for all its velocities (tile + shift spread) into
// shared memory (cp.async, double-buffered, out-of-frame samples zero-filled) and every thread accumulates
// its pixels x velocities in registers. When consecutive velocities share a shift at a frame (common near
// t_ref), the values already in registers are reused. N_in comes from per-column/per-row frame spans
// (closed form), never from per-sample counting. Results are reduced on the device: per velocity the
// maximum SNR and its pixel (64-bit atomicMax), and cells above threshold appended to a bounded buffer.
#include <cuda_runtime.h>

#include "cuda_check.hpp"
#include "kernel_params.hpp"
#include "search_device.cuh"

namespace st::gpu {
namespace {

__global__ void tileOffsetsKernel(SearchLaunch p, int* out, int tileCount) {
  const long long i = blockIdx.x * static_cast<long long>(blockDim.x) + threadIdx.x;
  if (i >= static_cast<long long>(tileCount) * p.frameCount) return;
  const int tile = static_cast<int>(i / p.frameCount);
  const int n = static_cast<int>(i % p.frameCount);
  const int tilesX = (p.nvx + p.vtileX - 1) / p.vtileX;
  const int ixBase = (tile % tilesX) * p.vtileX;
  const int iyBase = p.iy0 + (tile / tilesX) * p.vtileY;
  int sx[kVelPerBlock], sy[kVelPerBlock];
  int ox = 1 << 30, oy = 1 << 30;
  for (int k = 0; k < kVelPerBlock; ++k) {
    const int ix = min(ixBase + k % p.vtileX, p.nvx - 1);
    const int iy = min(iyBase + k / p.vtileX, p.iy1 - 1);
    sx[k] = p.shiftX[static_cast<long long>(ix) * p.frameCount + n];
    sy[k] = p.shiftY[static_cast<long long>(iy) * p.frameCount + n];
    ox = min(ox, sx[k]);
    oy = min(oy, sy[k]);
  }
  int* o = out + i * (kVelPerBlock + 2);
  o[0] = ox;
  o[1] = oy;
  for (int k = 0; k < kVelPerBlock; ++k)
    o[2 + k] = (sy[k] - oy) * p.pitch + (sx[k] - ox);
}

constexpr int kRy = kRowsPerThread;
constexpr int kK = kVelPerBlock;
constexpr int kOffs = kVelPerBlock + 2;

/// Issues the asynchronous copies of one stage (frames [n0, n0 + count)) into buffer `buf`.
__device__ void issueStage(const SearchLaunch& p, float* win, int* offs, int n0, int count, int tile, int x0,
                           int y0) {
  const int winSize = p.pitch * p.winRows;
  const int lane = threadIdx.x & 31;
  const int warp = threadIdx.x >> 5;
  for (int i = 0; i < count; ++i) {
    const int n = n0 + i;
    const int* to = p.tileOffsets + (static_cast<long long>(tile) * p.frameCount + n) * kOffs;
    if (threadIdx.x < kOffs) offs[i * kOffs + threadIdx.x] = to[threadIdx.x];
    const int gx0 = x0 + to[0];
    const int gy0 = y0 + to[1];
    const float* frame = p.frames + static_cast<long long>(n - p.frameBase) * p.width * p.height;
    float* w = win + i * winSize;
    for (int r = warp; r < p.winRows; r += kThreads / 32) {
      const int gy = gy0 + r;
      const bool rowIn = gy >= 0 && gy < p.height;
      for (int c = lane; c < p.pitch; c += 32) {
        const int gx = gx0 + c;
        const bool in = rowIn && gx >= 0 && gx < p.width;
        cpAsync4(w + r * p.pitch + c, in ? frame + static_cast<long long>(gy) * p.width + gx : frame, in);
      }
    }
  }
  cpAsyncCommit();
}

/// Adds one frame's window to the accumulators. kMode 0: a velocity whose offset equals the previous
/// one's reuses the values in registers (uniform branch); 1: every velocity loads (no branches); 2: the
/// reuse decided by predicated loads instead of branches.
template <int kMode, int kCx>
__device__ __forceinline__ void accumulateFrame(float (&acc)[kK][kRy][kCx], const float* w, const int* o,
                                                int rowStride) {
  int prev = -1;
  float v[kRy][kCx];
#pragma unroll
  for (int k = 0; k < kK; ++k) {
    const int off = o[k];
    if constexpr (kMode == 0) {
      if (off != prev) {  // uniform across the block: no divergence
#pragma unroll
        for (int r = 0; r < kRy; ++r) {
#pragma unroll
          for (int j = 0; j < kCx; ++j)
            v[r][j] = w[off + r * rowStride + 32 * j];
        }
      }
    } else if constexpr (kMode == 1) {
#pragma unroll
      for (int r = 0; r < kRy; ++r) {
#pragma unroll
        for (int j = 0; j < kCx; ++j)
          v[r][j] = w[off + r * rowStride + 32 * j];
      }
    } else {
      const int load = off != prev ? 1 : 0;
#pragma unroll
      for (int r = 0; r < kRy; ++r) {
#pragma unroll
        for (int j = 0; j < kCx; ++j) {
          if (k == 0) {
            v[r][j] = w[off + r * rowStride + 32 * j];
          } else {
            const unsigned a =
                static_cast<unsigned>(__cvta_generic_to_shared(w + off + r * rowStride + 32 * j));
            asm volatile("{\n .reg .pred q;\n setp.ne.b32 q, %2, 0;\n @q ld.shared.f32 %0, [%1];\n}"
                         : "+f"(v[r][j])
                         : "r"(a), "r"(load));
          }
        }
      }
    }
    prev = off;
#pragma unroll
    for (int r = 0; r < kRy; ++r) {
#pragma unroll
      for (int j = 0; j < kCx; ++j)
        acc[k][r][j] += v[r][j];
    }
  }
}

template <int kMode, int kCx>
__global__ void __launch_bounds__(kThreads, kCx == 4 ? 2 : 3) tiledSearchKernel(SearchLaunch p) {
  constexpr int kTileWidth = 32 * kCx;
  extern __shared__ float smem[];
  const int lane = threadIdx.x & 31;
  const int warp = threadIdx.x >> 5;
  // Velocity tiles vary fastest: blocks resident together share pixel tiles, so frame windows hit in L2.
  const int tile = blockIdx.x;
  const int x0 = blockIdx.y * kTileWidth;
  const int y0 = blockIdx.z * kTileH;
  const int tilesX = (p.nvx + p.vtileX - 1) / p.vtileX;
  const int ixBase = (tile % tilesX) * p.vtileX;
  const int iyBase = p.iy0 + (tile / tilesX) * p.vtileY;
  const int winSize = p.pitch * p.winRows;
  const int fs = p.framesPerStage;
  float* wins = smem;
  int* offs = reinterpret_cast<int*>(smem + 2 * fs * winSize);
  __shared__ unsigned long long blockKeys[kK];
  if (threadIdx.x < kK) blockKeys[threadIdx.x] = 0ull;

  const long long plane = static_cast<long long>(p.width) * p.height;
  float acc[kK][kRy][kCx];
#pragma unroll
  for (int k = 0; k < kK; ++k) {
    const int ix = ixBase + k % p.vtileX;
    const int iy = iyBase + k / p.vtileX;
    const bool vOk = ix < p.nvx && iy < p.iy1;
#pragma unroll
    for (int r = 0; r < kRy; ++r) {
#pragma unroll
      for (int j = 0; j < kCx; ++j) {
        const int x = x0 + lane + 32 * j;
        const int y = y0 + warp + 8 * r;
        float a = 0.0f;
        if (p.loadPartial && vOk && x < p.width && y < p.height) {
          a = p.partial[(static_cast<long long>(iy - p.iy0) * p.nvx + ix) * plane +
                        static_cast<long long>(y) * p.width + x];
        }
        acc[k][r][j] = a;
      }
    }
  }

  const int frames = p.f1 - p.f0;
  const int stages = (frames + fs - 1) / fs;
  if (stages > 0) issueStage(p, wins, offs, p.f0, min(fs, frames), tile, x0, y0);
  const int rowStride = 8 * p.pitch;
  for (int s = 0; s < stages; ++s) {
    const int buf = s & 1;
    if (s + 1 < stages) {
      const int n0 = p.f0 + (s + 1) * fs;
      issueStage(p, wins + (buf ^ 1) * fs * winSize, offs + (buf ^ 1) * fs * kOffs, n0, min(fs, p.f1 - n0),
                 tile, x0, y0);
    } else {
      cpAsyncCommit();  // an empty group keeps wait_group 1 meaning "stage s has landed"
    }
    cpAsyncWaitOne();
    __syncthreads();
    const int count = min(fs, frames - s * fs);
    for (int i = 0; i < count; ++i) {
      const float* w = wins + (buf * fs + i) * winSize + warp * p.pitch + lane;
      const int* o = offs + (buf * fs + i) * kOffs + 2;
      accumulateFrame<kMode, kCx>(acc, w, o, rowStride);
    }
    __syncthreads();
  }

#pragma unroll
  for (int k = 0; k < kK; ++k) {
    const int ix = ixBase + k % p.vtileX;
    const int iy = iyBase + k / p.vtileX;
    if (ix >= p.nvx || iy >= p.iy1) continue;  // uniform
    unsigned long long best = 0ull;
#pragma unroll
    for (int r = 0; r < kRy; ++r) {
#pragma unroll
      for (int j = 0; j < kCx; ++j) {
        const int x = x0 + lane + 32 * j;
        const int y = y0 + warp + 8 * r;
        if (x >= p.width || y >= p.height) continue;
        const long long at = (static_cast<long long>(iy - p.iy0) * p.nvx + ix) * plane +
                             static_cast<long long>(y) * p.width + x;
        const unsigned long long key = finishCell(p, acc[k][r][j], at, x, y, ix, iy);
        best = key > best ? key : best;
      }
    }
    if (p.finalize) {
      best = warpMax(best);
      if (lane == 0 && best != 0ull) atomicMax(&blockKeys[k], best);
    }
  }
  if (!p.finalize) return;
  __syncthreads();
  if (threadIdx.x < kK) {
    const int ix = ixBase + threadIdx.x % p.vtileX;
    const int iy = iyBase + threadIdx.x / p.vtileX;
    if (ix < p.nvx && iy < p.iy1 && blockKeys[threadIdx.x] != 0ull) {
      atomicMax(p.mapKeys + static_cast<long long>(iy) * p.nvx + ix, blockKeys[threadIdx.x]);
    }
  }
}

/// The naive reference: one thread per (pixel, velocity), every sample read from global memory and its
/// bounds checked, N_in counted per sample (an independent check of the closed form).
__global__ void naiveSearchKernel(SearchLaunch p) {
  const int pixel = blockIdx.x * blockDim.x + threadIdx.x;
  const int ix = blockIdx.y;
  const int iy = p.iy0 + blockIdx.z;
  const bool inImage = pixel < p.width * p.height;
  const int x = inImage ? pixel % p.width : 0;
  const int y = inImage ? pixel / p.width : 0;
  const long long plane = static_cast<long long>(p.width) * p.height;
  float sum = 0.0f;
  int nIn = 0;
  for (int n = p.f0; n < p.f1; ++n) {
    const int sx = x + p.shiftX[static_cast<long long>(ix) * p.frameCount + n];
    const int sy = y + p.shiftY[static_cast<long long>(iy) * p.frameCount + n];
    if (sx >= 0 && sx < p.width && sy >= 0 && sy < p.height) {
      sum += p.frames[(n - p.frameBase) * plane + static_cast<long long>(sy) * p.width + sx];
      ++nIn;
    }
  }
  const unsigned long long key = inImage ? scoreCell(p, sum, nIn, x, y, ix, iy) : 0ull;
  const unsigned long long best = warpMax(key);
  if ((threadIdx.x & 31) == 0 && best != 0ull)
    atomicMax(p.mapKeys + static_cast<long long>(iy) * p.nvx + ix, best);
}

}  // namespace

std::size_t tiledSharedBytes(int pitch, int winRows, int framesPerStage) {
  return static_cast<std::size_t>(2) * framesPerStage *
         (static_cast<std::size_t>(pitch) * winRows * sizeof(float) + kOffs * sizeof(int));
}

template <int kMode, int kCx>
void setShared(std::size_t sharedBytes) {
  ST_CUDA_CHECK(cudaFuncSetAttribute(tiledSearchKernel<kMode, kCx>,
                                     cudaFuncAttributeMaxDynamicSharedMemorySize,
                                     static_cast<int>(sharedBytes)));
}

void configureTiledKernel(std::size_t sharedBytes) {
  setShared<0, 4>(sharedBytes);
  setShared<1, 4>(sharedBytes);
  setShared<2, 4>(sharedBytes);
  setShared<0, 2>(sharedBytes);
  setShared<1, 2>(sharedBytes);
  setShared<2, 2>(sharedBytes);
}

int tiledTileWidth(int variant) {
  return variant >= 10 ? 64 : 128;
}

void launchTileOffsets(const SearchLaunch& p, int* tileOffsets, int tileCount, cudaStream_t stream) {
  const long long total = static_cast<long long>(tileCount) * p.frameCount;
  const int blocks = static_cast<int>((total + 255) / 256);
  tileOffsetsKernel<<<blocks, 256, 0, stream>>>(p, tileOffsets, tileCount);
  checkLaunch("tileOffsetsKernel");
}

void launchTiledSearch(const SearchLaunch& p, cudaStream_t stream) {
  const int tilesX = (p.nvx + p.vtileX - 1) / p.vtileX;
  const int tilesY = (p.iy1 - p.iy0 + p.vtileY - 1) / p.vtileY;
  const int tw = tiledTileWidth(p.variant);
  const dim3 grid(tilesX * tilesY, (p.width + tw - 1) / tw, (p.height + kTileH - 1) / kTileH);
  const std::size_t shared = tiledSharedBytes(p.pitch, p.winRows, p.framesPerStage);
  switch (p.variant) {
    case 1:
      tiledSearchKernel<1, 4><<<grid, kThreads, shared, stream>>>(p);
      break;
    case 2:
      tiledSearchKernel<2, 4><<<grid, kThreads, shared, stream>>>(p);
      break;
    case 10:
      tiledSearchKernel<0, 2><<<grid, kThreads, shared, stream>>>(p);
      break;
    case 11:
      tiledSearchKernel<1, 2><<<grid, kThreads, shared, stream>>>(p);
      break;
    case 12:
      tiledSearchKernel<2, 2><<<grid, kThreads, shared, stream>>>(p);
      break;
    default:
      tiledSearchKernel<0, 4><<<grid, kThreads, shared, stream>>>(p);
      break;
  }
  checkLaunch("tiledSearchKernel");
}

void launchNaiveSearch(const SearchLaunch& p, cudaStream_t stream) {
  const dim3 grid((p.width * p.height + 255) / 256, p.nvx, p.iy1 - p.iy0);
  naiveSearchKernel<<<grid, 256, 0, stream>>>(p);
  checkLaunch("naiveSearchKernel");
}

}  // namespace st::gpu

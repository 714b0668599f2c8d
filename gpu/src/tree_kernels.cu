// Kernels of the CUDA tree search (tree_kernel_params.hpp): one launch per level of the tree per tile (every
// node of the level, combine or direct), then the root kernel that sums the top `cut` levels in registers and
// scans the root's stacks (velocity map, cells above threshold). Sums are formed in exactly the CPU tree's
// order (core/search/tree_search.cpp), so the stacks are bit-identical to the CPU's.
#include "cuda_check.hpp"
#include "search_device.cuh"
#include "tree_kernel_params.hpp"

namespace st::gpu {
namespace {

constexpr int kLevelThreads = 256;
constexpr int kLevelWarps = kLevelThreads / 32;
/// Direct nodes of at most this many frames take the register path of treeLevelKernel.
constexpr int kDirectRegs = 4;

__global__ void __launch_bounds__(kLevelThreads) treeLevelKernel(TreeLevelLaunch p) {
  const int item = blockIdx.x * kLevelWarps + static_cast<int>(threadIdx.x / 32);
  if (item >= p.rows) return;
  const int lane = threadIdx.x & 31;
  const int2 jr = p.rowJobs[item];
  const TreeJob& j = p.jobs[jr.x];
  const int row = jr.y;
  float* out = p.out + j.out + static_cast<long long>(row) * j.pitch;
  const int2 rr = p.rowTab[j.rowTable + row];
  const int4* seg = p.segTab + j.segTable;
  if (!j.direct) {
    const float* a = p.in + j.left + static_cast<long long>(rr.x) * j.leftPitch;
    const float* b = p.in + j.right + static_cast<long long>(rr.y) * j.rightPitch;
    for (int s = 0; s < j.segments; ++s) {
      const int4 g = seg[s];
#pragma unroll 4
      for (int c = lane; c < g.y; c += 32)
        __stcs(out + g.x + c, __ldg(a + g.z + c) + __ldg(b + g.w + c));  // evict-first: keep the inputs
    }
    return;
  }
  // Direct: frames in time order, samples outside the image skipped (the CPU's zeros).
  const int m = j.last - j.first;
  const int* sy = p.shiftY + j.shiftY + rr.x * m;
  const long long plane = static_cast<long long>(p.width) * p.height;
  if (m <= kDirectRegs && !p.directPlain) {
    // Few frames (the deepest level: ~3 of the paper's 1500 over 512 nodes): each frame's row pointer and
    // row test once per warp, its x shift once per segment, in registers; the same sums in the same order.
    const float* rowPtr[kDirectRegs];
    bool rowIn[kDirectRegs];
#pragma unroll
    for (int k = 0; k < kDirectRegs; ++k) {
      const int yi = k < m ? p.y0 + rr.y + sy[k] : -1;
      rowIn[k] = yi >= 0 && yi < p.height;
      rowPtr[k] = p.frames +
                  (rowIn[k] ? p.frameIndex[j.first + k] * plane + static_cast<long long>(yi) * p.width : 0);
    }
    for (int s = 0; s < j.segments; ++s) {
      const int4 g = seg[s];
      const int* sx = p.shiftX + j.shiftX + g.z * m;
      int x0[kDirectRegs];
#pragma unroll
      for (int k = 0; k < kDirectRegs; ++k)
        x0[k] = k < m ? g.w + sx[k] : 0;
      for (int c = lane; c < g.y; c += 32) {
        float sum = 0.0f;
#pragma unroll
        for (int k = 0; k < kDirectRegs; ++k) {
          const int xi = x0[k] + c;
          if (rowIn[k] && xi >= 0 && xi < p.width) sum += __ldg(rowPtr[k] + xi);
        }
        __stcs(out + g.x + c, sum);
      }
    }
    return;
  }
  for (int s = 0; s < j.segments; ++s) {
    const int4 g = seg[s];
    const int* sx = p.shiftX + j.shiftX + g.z * m;
    for (int c = lane; c < g.y; c += 32) {
      float sum = 0.0f;
      for (int k = 0; k < m; ++k) {
        const int xi = g.w + c + sx[k];
        const int yi = p.y0 + rr.y + sy[k];
        if (xi >= 0 && xi < p.width && yi >= 0 && yi < p.height) {
          sum +=
              __ldg(p.frames + p.frameIndex[j.first + k] * plane + static_cast<long long>(yi) * p.width + xi);
        }
      }
      out[g.x + c] = sum;
    }
  }
}

/// A block scans kGx x kGy root velocities over 32 kCols columns and kTreeRootRows rows: warp w takes root vy
/// iy0 + w and its kGx vx in turn, each lane kCols columns 32 apart (independent loads in flight), all warps
/// on the same columns and row at about the same time, so neighbouring root velocities (which mostly read the
/// same cut stacks a pixel or two apart) share L1 lines (ncu, 1-column version: L1 hit rate 72%; latency-
/// bound at 30% occupancy, no unit above 45%). Measured on the paper problem (H100, cut 4): 1 column 24.2 ms
/// (108 registers) / 21.8 ms (80), 2 columns 20.0 ms (105 registers, the default), 4 columns 21.5 ms;
/// 2 x 4, 4 x 8, 4 x 2 velocities per block with 2 columns 19.8-20.8 ms; 8 x 8 or 4 x 8 with 1 column, or a
/// persistent grid of 1-8 blocks per SM, no better. Tried and
/// slower: staging each cut stack's 32-float chunks in shared memory per warp (plain 68 ms, cp.async
/// double-buffered 85 ms: the cut stacks change every 2-4 root velocities, so the chunks rarely fit and the
/// copies serialise), reusing a sample between neighbouring vx in registers (47 ms, a dependency chain),
/// all of a thread's loads before its scoring (234 registers or spills, 23.6-26.6 ms).
template <int kCut, int kGx, int kGy, int kMinBlocks, int kCols>
__global__ void __launch_bounds__(32 * kGy, kMinBlocks) treeRootKernel(TreeRootLaunch p) {
  constexpr int kN = 1 << kCut;
  __shared__ int colOff[kGx][kN];
  __shared__ int pitch[kN];
  const int colTiles = (p.width + 32 * kCols - 1) / (32 * kCols);
  const int x0 = (blockIdx.x % colTiles) * 32 * kCols;
  const int ix0 = (blockIdx.x / colTiles) * kGx;
  const int iy = blockIdx.y * kGy + static_cast<int>(threadIdx.x / 32);
  const int r0 = blockIdx.z * kTreeRootRows;
  const int lane = threadIdx.x & 31;
  for (int i = threadIdx.x; i < kGx * kN; i += 32 * kGy) {
    const int gx = i / kN;
    const int c = i % kN;
    colOff[gx][c] = p.colBase[c * p.nvx + min(ix0 + gx, p.nvx - 1)] + x0;
    if (gx == 0) pitch[c] = p.cutPitch[c];
  }
  __syncthreads();
  if (iy >= p.nvy) return;  // whole warps; no block barrier below
  // Float offsets in the arena: < 2^31, TreeDevicePlan keeps arenas below kTreeMaxArenaFloats.
  int rowOff[kN];
#pragma unroll
  for (int c = 0; c < kN; ++c)
    rowOff[c] = static_cast<int>(p.cutBase[c]) + (p.rowBase[c * p.nvy + iy] + r0) * pitch[c];
  int2 sx[kGx][kCols];
#pragma unroll
  for (int gx = 0; gx < kGx; ++gx) {
#pragma unroll
    for (int k = 0; k < kCols; ++k) {
      const int x = x0 + lane + 32 * k;
      sx[gx][k] = x < p.width ? p.spanX[static_cast<long long>(min(ix0 + gx, p.nvx - 1)) * p.width + x]
                              : int2{0, -1};  // no frame: the cell is skipped
    }
  }
  // Each velocity's best cell so far: its SNR as ordered bits (packKey's order) and its pixel. A thread
  // visits its cells in increasing pixel order (rows, then columns), so a strictly greater SNR alone keeps
  // the lowest pixel of a tie, as the packed 64-bit maximum did (one 32-bit compare per cell instead).
  unsigned bestBits[kGx];
  int bestPixel[kGx];
#pragma unroll
  for (int gx = 0; gx < kGx; ++gx) {
    bestBits[gx] = 0u;
    bestPixel[gx] = -1;
  }
  const int minFrames = max(1, p.minFrames);
  // The lane's column; a thread's columns k at + 32 k (immediate offsets). Lanes past the image read
  // columns past the row's end (the next segment, or the arena's slack at its end, kTreeArenaSlack): their
  // cells are skipped below.
  const float* in = p.in + lane;
  const int2* spanY = p.spanY + static_cast<long long>(iy) * p.height;
  const int rEnd = min(kTreeRootRows, min(p.tileRows - r0, p.height - p.y0 - r0));
  for (int r = 0; r < rEnd; ++r) {
    const int y = p.y0 + r0 + r;
    const int2 sy = spanY[y];
#pragma unroll
    for (int gx = 0; gx < kGx; ++gx) {
      const int ix = ix0 + gx;
      if (ix >= p.nvx) continue;
      float v[kCols][kN];
#pragma unroll
      for (int c = 0; c < kN; ++c) {
        const float* a = in + (rowOff[c] + colOff[gx][c]);
#pragma unroll
        for (int k = 0; k < kCols; ++k)
          v[k][c] = __ldg(a + 32 * k);
      }
#pragma unroll
      for (int k = 0; k < kCols; ++k) {
#pragma unroll
        for (int s = 1; s < kN; s *= 2) {
#pragma unroll
          for (int i = 0; i < kN; i += 2 * s)
            v[k][i] = v[k][i] + v[k][i + s];
        }
        const float sum = v[k][0];
        const int x = x0 + lane + 32 * k;
        const int nIn = !p.maskX ? framesInBoth(sx[gx][k], sy)
                        : x < p.width
                            ? framesInMasks(p.maskX, p.maskY, p.maskWords, ix, x, p.width, iy, y, p.height)
                            : 0;
        if (nIn < minFrames) continue;
        const float snr = sum * __ldg(p.invNorm + nIn);
        if (snr > p.snrThreshold) {
          const unsigned long long slot = atomicAdd(p.cellCount, 1ull);
          if (slot < p.cellCapacity) p.cells[slot] = DeviceCell{x, y, ix, iy, sum, snr, nIn, 0};
        }
        const unsigned bits = orderedBits(snr);
        if (bestPixel[gx] < 0 || bits > bestBits[gx]) {
          bestBits[gx] = bits;
          bestPixel[gx] = y * p.width + x;
        }
      }
    }
#pragma unroll
    for (int c = 0; c < kN; ++c)
      rowOff[c] += pitch[c];
  }
#pragma unroll
  for (int gx = 0; gx < kGx; ++gx) {
    const unsigned long long key = bestPixel[gx] < 0
                                       ? 0ull
                                       : ((static_cast<unsigned long long>(bestBits[gx]) << 32) |
                                          (0xFFFFFFFFull - static_cast<unsigned>(bestPixel[gx])));  // packKey
    const unsigned long long b = warpMax(key);
    if (lane == 0 && b != 0ull) atomicMax(p.mapKeys + iy * p.nvx + ix0 + gx, b);
  }
}

template <int kGx, int kGy, int kMinBlocks = 1, int kCols = 1>
void launchRootShape(const TreeRootLaunch& p, cudaStream_t stream) {
  const int colTiles = (p.width + 32 * kCols - 1) / (32 * kCols);
  const dim3 grid(colTiles * ((p.nvx + kGx - 1) / kGx), (p.nvy + kGy - 1) / kGy,
                  (p.tileRows + kTreeRootRows - 1) / kTreeRootRows);
  switch (p.cut) {
    case 1:
      treeRootKernel<1, kGx, kGy, kMinBlocks, kCols><<<grid, 32 * kGy, 0, stream>>>(p);
      break;
    case 2:
      treeRootKernel<2, kGx, kGy, kMinBlocks, kCols><<<grid, 32 * kGy, 0, stream>>>(p);
      break;
    case 3:
      treeRootKernel<3, kGx, kGy, kMinBlocks, kCols><<<grid, 32 * kGy, 0, stream>>>(p);
      break;
    case 4:
      treeRootKernel<4, kGx, kGy, kMinBlocks, kCols><<<grid, 32 * kGy, 0, stream>>>(p);
      break;
    default:
      throw GpuError("tree root kernel: cut " + std::to_string(p.cut) + " not compiled");
  }
}

}  // namespace

void loadTreeKernels() {
  cudaFuncAttributes a{};
  ST_CUDA_CHECK(cudaFuncGetAttributes(&a, treeLevelKernel));
}

void launchTreeLevel(const TreeLevelLaunch& p, cudaStream_t stream) {
  if (p.rows <= 0) return;
  treeLevelKernel<<<(p.rows + kLevelWarps - 1) / kLevelWarps, kLevelThreads, 0, stream>>>(p);
  checkLaunch("treeLevelKernel");
}

void launchTreeRoot(const TreeRootLaunch& p, cudaStream_t stream) {
  switch (p.shape) {
    case 1:
      launchRootShape<8, 8>(p, stream);
      break;
    case 2:
      launchRootShape<2, 4>(p, stream);
      break;
    case 3:
      launchRootShape<4, 8>(p, stream);
      break;
    case 4:
      launchRootShape<4, 4, 8>(p, stream);
      break;
    case 5:
      launchRootShape<4, 4>(p, stream);
      break;
    case 6:
      launchRootShape<4, 4, 6>(p, stream);
      break;
    case 7:
      launchRootShape<4, 4, 5, 2>(p, stream);
      break;
    case 8:
      launchRootShape<4, 4, 3, 4>(p, stream);
      break;
    case 9:
      launchRootShape<8, 4, 4, 2>(p, stream);
      break;
    case 10:
      launchRootShape<2, 4, 6, 2>(p, stream);
      break;
    case 11:
      launchRootShape<4, 8, 2, 2>(p, stream);
      break;
    case 12:
      launchRootShape<4, 2, 8, 2>(p, stream);
      break;
    case 13:
      launchRootShape<2, 4, 8, 2>(p, stream);
      break;
    default:
      launchRootShape<4, 4, 4, 2>(p, stream);
  }
  checkLaunch("treeRootKernel");
}

}  // namespace st::gpu

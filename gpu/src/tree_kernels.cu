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
constexpr int kRootThreads = 128;
constexpr int kRootGx = 4;  // root velocities per block along vx
constexpr int kRootGy = 4;  // and along vy

__global__ void __launch_bounds__(kLevelThreads) treeLevelKernel(TreeLevelLaunch p) {
  const int2 jr = p.rowJobs[blockIdx.x];
  const TreeJob& j = p.jobs[jr.x];
  const int row = jr.y;
  float* out = p.out + j.out + static_cast<long long>(row) * j.pitch;
  const int2 rr = p.rowTab[j.rowTable + row];
  const int2* ct = p.colTab + j.colTable;
  if (!j.direct) {
    const float* a = p.in + j.left + static_cast<long long>(rr.x) * j.leftPitch;
    const float* b = p.in + j.right + static_cast<long long>(rr.y) * j.rightPitch;
    for (int c = threadIdx.x; c < j.pitch; c += kLevelThreads) {
      const int2 cc = ct[c];
      out[c] = __ldg(a + cc.x) + __ldg(b + cc.y);
    }
    return;
  }
  // Direct: frames in time order, samples outside the image skipped (the CPU's zeros).
  const int m = j.last - j.first;
  const int* sy = p.shiftY + j.shiftY + rr.x * m;
  const long long plane = static_cast<long long>(p.width) * p.height;
  for (int c = threadIdx.x; c < j.pitch; c += kLevelThreads) {
    const int2 cc = ct[c];
    const int* sx = p.shiftX + j.shiftX + cc.x * m;
    float s = 0.0f;
    for (int k = 0; k < m; ++k) {
      const int xi = cc.y + sx[k];
      const int yi = p.y0 + rr.y + sy[k];
      if (xi >= 0 && xi < p.width && yi >= 0 && yi < p.height) {
        s += __ldg(p.frames + p.frameIndex[j.first + k] * plane + static_cast<long long>(yi) * p.width + xi);
      }
    }
    out[c] = s;
  }
}

/// A block scans kRootGx x kRootGy root velocities over kRootThreads columns and kTreeRootRows rows, rows
/// outermost: the cut stacks one row needs are shared by neighbouring root velocities (about 2 x 2 per cut
/// stack), so after the first velocity of the group they come from L1, not L2.
template <int kCut>
__global__ void __launch_bounds__(kRootThreads) treeRootKernel(TreeRootLaunch p) {
  constexpr int kN = 1 << kCut;
  constexpr int kG = kRootGx * kRootGy;
  __shared__ long long base[kG][kN];
  __shared__ int valid[kG];
  const int colTiles = (p.width + kRootThreads - 1) / kRootThreads;
  const int x0 = (blockIdx.x % colTiles) * kRootThreads;
  const int ix0 = (blockIdx.x / colTiles) * kRootGx;
  const int iy0 = blockIdx.y * kRootGy;
  const int r0 = blockIdx.z * kTreeRootRows;
  for (int i = threadIdx.x; i < kG * kN; i += kRootThreads) {
    const int g = i / kN;
    const int c = i % kN;
    const int ix = min(ix0 + g % kRootGx, p.nvx - 1);
    const int iy = min(iy0 + g / kRootGx, p.nvy - 1);
    base[g][c] = p.cutBase[c] + static_cast<long long>(p.rowBase[c * p.nvy + iy] + r0) * p.cutPitch[c] +
                 p.colBase[c * p.nvx + ix] + x0;
    if (c == 0) valid[g] = ix0 + g % kRootGx < p.nvx && iy0 + g / kRootGx < p.nvy;
  }
  __syncthreads();
  int pitch[kN];
#pragma unroll
  for (int c = 0; c < kN; ++c)
    pitch[c] = p.cutPitch[c];
  const int x = x0 + threadIdx.x;
  const bool inImage = x < p.width;
  int2 sx[kRootGx];
#pragma unroll
  for (int gx = 0; gx < kRootGx; ++gx)
    sx[gx] = inImage ? p.spanX[static_cast<long long>(min(ix0 + gx, p.nvx - 1)) * p.width + x] : int2{0, -1};
  unsigned long long best[kG];
#pragma unroll
  for (int g = 0; g < kG; ++g)
    best[g] = 0ull;
  const int rEnd = min(kTreeRootRows, min(p.tileRows - r0, p.height - p.y0 - r0));
  for (int r = 0; r < rEnd; ++r) {
    const int y = p.y0 + r0 + r;
#pragma unroll
    for (int g = 0; g < kG; ++g) {
      if (!valid[g] || !inImage) continue;
      const int ix = ix0 + g % kRootGx;
      const int iy = iy0 + g / kRootGx;
      float v[kN];
#pragma unroll
      for (int c = 0; c < kN; ++c)
        v[c] = __ldg(p.in + base[g][c] + static_cast<long long>(r) * pitch[c] + threadIdx.x);
#pragma unroll
      for (int s = 1; s < kN; s *= 2) {
#pragma unroll
        for (int i = 0; i < kN; i += 2 * s)
          v[i] = v[i] + v[i + s];
      }
      const int nIn = framesInBoth(sx[g % kRootGx], p.spanY[static_cast<long long>(iy) * p.height + y]);
      if (nIn <= 0 || nIn < p.minFrames) continue;
      const float snr = v[0] * p.invNorm[nIn];
      if (snr > p.snrThreshold) {
        const unsigned long long slot = atomicAdd(p.cellCount, 1ull);
        if (slot < p.cellCapacity) p.cells[slot] = DeviceCell{x, y, ix, iy, v[0], snr, nIn, 0};
      }
      const unsigned long long key = packKey(snr, y * p.width + x);
      best[g] = key > best[g] ? key : best[g];
    }
  }
#pragma unroll
  for (int g = 0; g < kG; ++g) {
    const unsigned long long b = warpMax(best[g]);
    if ((threadIdx.x & 31) == 0 && b != 0ull && valid[g])
      atomicMax(p.mapKeys + (iy0 + g / kRootGx) * p.nvx + ix0 + g % kRootGx, b);
  }
}

}  // namespace

void launchTreeLevel(const TreeLevelLaunch& p, cudaStream_t stream) {
  if (p.rows <= 0) return;
  treeLevelKernel<<<p.rows, kLevelThreads, 0, stream>>>(p);
  checkLaunch("treeLevelKernel");
}

void launchTreeRoot(const TreeRootLaunch& p, cudaStream_t stream) {
  const int colTiles = (p.width + kRootThreads - 1) / kRootThreads;
  const dim3 grid(colTiles * ((p.nvx + kRootGx - 1) / kRootGx), (p.nvy + kRootGy - 1) / kRootGy,
                  (p.tileRows + kTreeRootRows - 1) / kTreeRootRows);
  switch (p.cut) {
    case 1:
      treeRootKernel<1><<<grid, kRootThreads, 0, stream>>>(p);
      break;
    case 2:
      treeRootKernel<2><<<grid, kRootThreads, 0, stream>>>(p);
      break;
    case 3:
      treeRootKernel<3><<<grid, kRootThreads, 0, stream>>>(p);
      break;
    case 4:
      treeRootKernel<4><<<grid, kRootThreads, 0, stream>>>(p);
      break;
    default:
      throw GpuError("tree root kernel: cut " + std::to_string(p.cut) + " not compiled");
  }
  checkLaunch("treeRootKernel");
}

}  // namespace st::gpu

// Kernels of residual_means.hpp: stats::removeResidualMeans on the device.
#include <cmath>
#include <cstdint>

#include "cuda_check.hpp"
#include "residual_means.hpp"

namespace st::gpu {
namespace {

constexpr int kThreads = 256;
constexpr int kStartMax = 2048;  // strided samples of a cell: ceil(size / max(1, size / 1024)) < 2048

// Ascending bitonic sort of s[0, kStartMax) (padded with +inf) by the whole block.
__device__ void bitonicSort(float* s) {
  for (int k = 2; k <= kStartMax; k <<= 1) {
    for (int j = k >> 1; j > 0; j >>= 1) {
      for (int i = threadIdx.x; i < kStartMax; i += blockDim.x) {
        const int l = i ^ j;
        if (l > i) {
          const bool up = (i & k) == 0;
          const float a = s[i], b = s[l];
          if ((a > b) == up) {
            s[i] = b;
            s[l] = a;
          }
        }
      }
      __syncthreads();
    }
  }
}

template <class T>
__device__ T blockSum(T v, T* scratch) {
  scratch[threadIdx.x] = v;
  __syncthreads();
  for (int half = kThreads / 2; half > 0; half /= 2) {
    if (threadIdx.x < half) scratch[threadIdx.x] += scratch[threadIdx.x + half];
    __syncthreads();
  }
  const T out = scratch[0];
  __syncthreads();
  return out;
}

__device__ __forceinline__ bool usable(float v) {
  return v != 0.0f && isfinite(v);
}

// One block per (cell, frame): core/stats/noise_model.cpp clippedMean of the cell's non-zero finite values.
__global__ void __launch_bounds__(kThreads) residualCellMeansKernel(ResidualMeansLaunch p) {
  __shared__ float start[kStartMax];
  __shared__ double dsum[kThreads];
  __shared__ unsigned long long csum[kThreads];
  const int cell = blockIdx.x, n = blockIdx.y;
  const int i = cell % p.nx, j = cell / p.nx;
  const int x0 = i * p.mesh, y0 = j * p.mesh;
  const int cw = min(p.mesh, p.width - x0), ch = min(p.mesh, p.height - y0);
  const int total = cw * ch;
  const float* f = p.pix + static_cast<std::size_t>(n) * p.width * p.height;
  auto at = [&](int l) { return f[static_cast<std::size_t>(y0 + l / cw) * p.width + x0 + l % cw]; };
  // Each thread a contiguous chunk of the cell in row-major order: counts, then the compacted index of each
  // usable value (the CPU's gathering order) for the strided start samples.
  const int chunk = (total + kThreads - 1) / kThreads;
  const int l0 = min(total, static_cast<int>(threadIdx.x) * chunk), l1 = min(total, l0 + chunk);
  unsigned long long mine = 0;
  for (int l = l0; l < l1; ++l)
    mine += usable(at(l));
  // Exclusive scan of the counts (thread order = row-major order).
  csum[threadIdx.x] = mine;
  __syncthreads();
  for (int off = 1; off < kThreads; off <<= 1) {
    const unsigned long long add = threadIdx.x >= off ? csum[threadIdx.x - off] : 0ull;
    __syncthreads();
    csum[threadIdx.x] += add;
    __syncthreads();
  }
  const long long size = static_cast<long long>(csum[kThreads - 1]);
  long long idx = static_cast<long long>(csum[threadIdx.x] - mine);
  __syncthreads();
  double* out = p.means + (static_cast<std::size_t>(n) * p.ny + j) * p.nx + i;
  if (size < p.minCount) {
    if (threadIdx.x == 0) *out = nan("");
    return;
  }
  const long long stride = max(1ll, size / 1024);
  const int count = static_cast<int>((size + stride - 1) / stride);
  for (int s = threadIdx.x; s < kStartMax; s += blockDim.x)
    start[s] = INFINITY;
  __syncthreads();
  for (int l = l0; l < l1; ++l) {
    const float v = at(l);
    if (!usable(v)) continue;
    if (idx % stride == 0) start[idx / stride] = v;
    ++idx;
  }
  __syncthreads();
  bitonicSort(start);
  double centre = start[count / 2];
  __syncthreads();
  const float cf = static_cast<float>(centre);
  for (int s = threadIdx.x; s < kStartMax; s += blockDim.x)
    start[s] = s < count ? fabsf(start[s] - cf) : INFINITY;
  __syncthreads();
  bitonicSort(start);
  double sigma = 1.4826 * start[count / 2];
  if (!(sigma > 0.0)) {
    if (threadIdx.x == 0) *out = centre;
    return;
  }
  unsigned long long previous = 0;
  for (int it = 0; it < 5; ++it) {
    double s = 0.0, ss = 0.0;
    unsigned long long c = 0;
    const double limit = p.clipSigma * sigma;
    for (int l = l0; l < l1; ++l) {
      const float x = at(l);
      if (!usable(x)) continue;
      const double d = __dsub_rn(static_cast<double>(x), centre);
      if (fabs(d) <= limit) {
        s = __dadd_rn(s, d);
        ss = __dadd_rn(ss, __dmul_rn(d, d));
        ++c;
      }
    }
    s = blockSum(s, dsum);
    ss = blockSum(ss, dsum);
    c = blockSum(c, csum);
    if (c < static_cast<unsigned long long>(p.minCount)) break;
    const double m = __ddiv_rn(s, static_cast<double>(c));
    centre = __dadd_rn(centre, m);
    sigma = sqrt(fmax(0.0, __dsub_rn(__ddiv_rn(ss, static_cast<double>(c)), __dmul_rn(m, m))));
    if (!(sigma > 0.0) || c == previous) break;
    previous = c;
  }
  if (threadIdx.x == 0) *out = centre;
}

// The CPU's separable bilinear interpolation between cell centres, in its double arithmetic.
__global__ void residualSubtractKernel(float* pix, int width, int height, int mesh, int nx, int ny,
                                       const double* means, const unsigned char* skip) {
  const int x = blockIdx.x * blockDim.x + threadIdx.x;
  const int y = blockIdx.y;
  const int n = blockIdx.z;
  if (x >= width || skip[n]) return;
  float& v = pix[(static_cast<std::size_t>(n) * height + y) * width + x];
  if (v == 0.0f || !isfinite(v)) return;
  const double* m = means + static_cast<std::size_t>(n) * nx * ny;
  const double wy = fmin(fmax(__dsub_rn(__ddiv_rn(y + 0.5, mesh), 0.5), 0.0), static_cast<double>(ny - 1));
  const int j0 = static_cast<int>(wy), j1 = min(j0 + 1, ny - 1);
  const double fy = __dsub_rn(wy, j0);
  const double u = fmin(fmax(__dsub_rn(__ddiv_rn(x + 0.5, mesh), 0.5), 0.0), static_cast<double>(nx - 1));
  const int i0 = static_cast<int>(u), i1 = min(i0 + 1, nx - 1);
  const double fx = __dsub_rn(u, i0);
  auto row = [&](int i) {
    return __dadd_rn(__dmul_rn(m[j0 * nx + i], __dsub_rn(1.0, fy)), __dmul_rn(m[j1 * nx + i], fy));
  };
  const double level = __dadd_rn(__dmul_rn(row(i0), __dsub_rn(1.0, fx)), __dmul_rn(row(i1), fx));
  v -= static_cast<float>(level);
}

}  // namespace

void launchResidualCellMeans(const ResidualMeansLaunch& p, cudaStream_t s) {
  for (int n0 = 0; n0 < p.nf; n0 += 65535) {
    ResidualMeansLaunch q = p;
    const int count = p.nf - n0 < 65535 ? p.nf - n0 : 65535;
    q.pix = p.pix + static_cast<std::size_t>(n0) * p.width * p.height;
    q.means = p.means + static_cast<std::size_t>(n0) * p.nx * p.ny;
    q.nf = count;
    residualCellMeansKernel<<<dim3(p.nx * p.ny, count), kThreads, 0, s>>>(q);
    checkLaunch("residualCellMeansKernel");
  }
}

void launchResidualSubtract(float* pix, int width, int height, int nf, int mesh, int nx, int ny,
                            const double* means, const unsigned char* skip, cudaStream_t s) {
  for (int n0 = 0; n0 < nf; n0 += 65535) {
    const int count = nf - n0 < 65535 ? nf - n0 : 65535;
    residualSubtractKernel<<<dim3((width + 127) / 128, height, count), 128, 0, s>>>(
        pix + static_cast<std::size_t>(n0) * width * height, width, height, mesh, nx, ny,
        means + static_cast<std::size_t>(n0) * nx * ny, skip + n0);
    checkLaunch("residualSubtractKernel");
  }
}

}  // namespace st::gpu

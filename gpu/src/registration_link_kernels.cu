// Registration's sampled links on the device (registration_link_kernels.hpp).
#include "registration_link_kernels.hpp"

#include <cmath>

#include "cuda_check.hpp"
#include "phase_fft_device.cuh"

namespace st::gpu {
namespace {

using namespace fft;

constexpr int kThreads = 256;
constexpr int kStatsThreads = 1024;

// Order-preserving keys of finite floats (a larger float, a larger key) and back.
__device__ __forceinline__ unsigned floatKey(float f) {
  const unsigned u = __float_as_uint(f);
  return (u & 0x80000000u) ? ~u : (u | 0x80000000u);
}
__device__ __forceinline__ float keyFloat(unsigned k) {
  return __uint_as_float((k & 0x80000000u) ? (k & 0x7fffffffu) : ~k);
}

// The k-th smallest (from 0) of v[0, n), by its key's bytes from the most significant (a radix select): the
// value std::nth_element puts at k. Every thread of the block must call it.
__device__ float selectKth(const float* v, int n, int k) {
  __shared__ unsigned hist[256];
  __shared__ unsigned prefix, mask;
  __shared__ int rank;
  if (threadIdx.x == 0) prefix = 0u, mask = 0u, rank = k;
  __syncthreads();
  for (int shift = 24; shift >= 0; shift -= 8) {
    for (int b = threadIdx.x; b < 256; b += blockDim.x)
      hist[b] = 0u;
    __syncthreads();
    const unsigned pre = prefix, msk = mask;
    for (int i = threadIdx.x; i < n; i += blockDim.x) {
      const unsigned key = floatKey(v[i]);
      if ((key & msk) == pre) atomicAdd(&hist[(key >> shift) & 255u], 1u);
    }
    __syncthreads();
    if (threadIdx.x == 0) {
      unsigned below = 0u;
      for (unsigned b = 0; b < 256u; ++b) {
        if (below + hist[b] > static_cast<unsigned>(rank)) {
          prefix |= b << shift;
          mask |= 255u << shift;
          rank -= static_cast<int>(below);
          break;
        }
        below += hist[b];
      }
    }
    __syncthreads();
  }
  return keyFloat(prefix);
}

// Each slot's frame's sampled median and sigma (core's starImage: every 7th pixel, unmasked and finite; the
// median, then 1.4826 x the median absolute deviation, at least 1e-12; 0 and 1 with 10 samples or fewer).
__global__ void starStats(RegistrationLinkLaunch p) {
  const int slot = blockIdx.x;
  const std::size_t np = static_cast<std::size_t>(p.width) * p.height;
  const float* f = p.frames + static_cast<std::size_t>(p.slotFrame[slot]) * np;
  const std::uint8_t* m = p.masks ? p.masks + static_cast<std::size_t>(slot) * np : nullptr;
  float* v = p.samples + static_cast<std::size_t>(slot) * p.sampleStride;
  __shared__ int count;
  if (threadIdx.x == 0) count = 0;
  __syncthreads();
  for (std::size_t i = 7 * static_cast<std::size_t>(threadIdx.x); i < np;
       i += 7 * static_cast<std::size_t>(blockDim.x)) {
    if (m && m[i]) continue;
    const float x = f[i];
    if (!isfinite(x)) continue;
    v[atomicAdd(&count, 1)] = x;
  }
  __syncthreads();
  const int n = count;
  float med = 0.0f, sig = 1.0f;
  if (n > 10) {
    med = selectKth(v, n, n / 2);
    for (int i = threadIdx.x; i < n; i += blockDim.x)
      v[i] = fabsf(__fsub_rn(v[i], med));
    __syncthreads();
    sig = fmaxf(__fmul_rn(1.4826f, selectKth(v, n, n / 2)), 1e-12f);
  }
  if (threadIdx.x == 0) p.median[slot] = med, p.sigma[slot] = sig;
}

// Each slot's star image: the bin's unmasked, finite pixels less the median, summed in row order, in the
// binned sigma, zeroed below 2.5 and clipped at 30, tapered.
__global__ void starImages(RegistrationLinkLaunch p) {
  const int slot = blockIdx.y;
  const int idx = blockIdx.x * blockDim.x + threadIdx.x;
  if (idx >= p.bw * p.bh) return;
  const int bx = idx % p.bw, by = idx / p.bw;
  const std::size_t np = static_cast<std::size_t>(p.width) * p.height;
  const float* f = p.frames + static_cast<std::size_t>(p.slotFrame[slot]) * np;
  const std::uint8_t* m = p.masks ? p.masks + static_cast<std::size_t>(slot) * np : nullptr;
  const float med = p.median[slot];
  const float scale = __fdiv_rn(1.0f, __fmul_rn(p.sigma[slot], static_cast<float>(p.bin)));
  float s = 0.0f;
  for (int j = 0; j < p.bin; ++j) {
    const std::size_t row = static_cast<std::size_t>(by * p.bin + j) * p.width;
    for (int i = 0; i < p.bin; ++i) {
      const std::size_t k = row + static_cast<std::size_t>(bx * p.bin + i);
      if (m && m[k]) continue;
      const float x = f[k];
      if (!isfinite(x)) continue;
      s = __fadd_rn(s, __fsub_rn(x, med));
    }
  }
  float v = __fmul_rn(s, scale);
  v = v < 2.5f ? 0.0f : fminf(v, 30.0f);
  p.images[static_cast<std::size_t>(slot) * p.bw * p.bh + idx] =
      __fmul_rn(v, __fmul_rn(p.taperY[by], p.taperX[bx]));
}

// Each slot's image rows transformed along x.
__global__ void rowsForward(RegistrationLinkLaunch p) {
  extern __shared__ float2 sh[];
  const int y = blockIdx.x, slot = blockIdx.y, nx = p.x.n;
  const float* in = p.images + (static_cast<std::size_t>(slot) * p.bh + y) * p.bw;
  for (int i = threadIdx.x; i < nx; i += blockDim.x)
    sh[reversedPos(i, p.x)] = make_float2(in[i], 0.0f);
  __syncthreads();
  fftShared(sh, p.x, false);
  float2* out = p.spectra + (static_cast<std::size_t>(slot) * p.bh + y) * nx;
  for (int i = threadIdx.x; i < nx; i += blockDim.x)
    out[i] = sh[i];
}

// Column x of a pair's two spectra transformed along y, A conj(B) high-passed (the high-pass of the
// frequency's mirror on the r2c half spectrum past its middle), and transformed back along y.
__global__ void columnsCrossCorrelation(RegistrationLinkLaunch p) {
  extern __shared__ float2 sh[];
  const int x = blockIdx.x, pair = blockIdx.y, nx = p.x.n, ny = p.y.n;
  float2* sa = sh;
  float2* sb = sh + ny;
  const float2* a = p.spectra + static_cast<std::size_t>(p.pairSlots[2 * pair]) * nx * ny;
  const float2* b = p.spectra + static_cast<std::size_t>(p.pairSlots[2 * pair + 1]) * nx * ny;
  for (int i = threadIdx.x; i < ny; i += blockDim.x) {
    const int r = reversedPos(i, p.y);
    sa[r] = a[static_cast<std::size_t>(i) * nx + x];
    sb[r] = b[static_cast<std::size_t>(i) * nx + x];
  }
  __syncthreads();
  fftShared(sa, p.y, false);
  fftShared(sb, p.y, false);
  const int hw = nx / 2 + 1, kx = min(x, nx - x);
  for (int i = threadIdx.x; i < ny; i += blockDim.x) {
    const float2 fa = sa[i], fb = sb[i];
    const float g = p.highPass[static_cast<std::size_t>(i) * hw + kx];
    const float re = __fadd_rn(__fmul_rn(fa.x, fb.x), __fmul_rn(fa.y, fb.y));
    const float im = __fsub_rn(__fmul_rn(fa.y, fb.x), __fmul_rn(fa.x, fb.y));
    sb[i] = make_float2(__fmul_rn(g, re), __fmul_rn(g, im));
  }
  __syncthreads();
  for (int i = threadIdx.x; i < ny; i += blockDim.x)
    sa[reversedPos(i, p.y)] = sb[i];
  __syncthreads();
  fftShared(sa, p.y, true);
  float2* out = p.products + static_cast<std::size_t>(pair) * nx * ny;
  for (int i = threadIdx.x; i < ny; i += blockDim.x)
    out[static_cast<std::size_t>(i) * nx + x] = sa[i];
}

// The better of two peak candidates: the larger value, of equal ones the first in raster order.
__device__ __forceinline__ bool better(float v, int idx, float bv, int bidx) {
  return v > bv || (v == bv && idx < bidx);
}

// Block-wide: the best (value, index) and the sums; valid in thread 0.
__device__ void reduceRow(float& v, int& idx, double& sum, double& sum2) {
  __shared__ float rv[kThreads];
  __shared__ int ri[kThreads];
  __shared__ double rs[kThreads], rs2[kThreads];
  rv[threadIdx.x] = v, ri[threadIdx.x] = idx, rs[threadIdx.x] = sum, rs2[threadIdx.x] = sum2;
  __syncthreads();
  for (int half = blockDim.x / 2; half > 0; half /= 2) {
    if (threadIdx.x < half) {
      const int o = threadIdx.x + half;
      if (better(rv[o], ri[o], rv[threadIdx.x], ri[threadIdx.x]))
        rv[threadIdx.x] = rv[o], ri[threadIdx.x] = ri[o];
      rs[threadIdx.x] += rs[o];
      rs2[threadIdx.x] += rs2[o];
    }
    __syncthreads();
  }
  v = rv[0], idx = ri[0], sum = rs[0], sum2 = rs2[0];
}

// Row y of a pair's product transformed back along x: its real part is the surface's row (unscaled, as
// FFTW's c2r); the row's first largest value and its sums.
__global__ void rowsInverse(RegistrationLinkLaunch p) {
  extern __shared__ float2 sh[];
  const int y = blockIdx.x, pair = blockIdx.y, nx = p.x.n, ny = p.y.n;
  const float2* in = p.products + (static_cast<std::size_t>(pair) * ny + y) * nx;
  for (int i = threadIdx.x; i < nx; i += blockDim.x)
    sh[reversedPos(i, p.x)] = in[i];
  __syncthreads();
  fftShared(sh, p.x, true);
  float* out = p.surface + (static_cast<std::size_t>(pair) * ny + y) * nx;
  float bv = -INFINITY;
  int bidx = 0x7fffffff;
  double sum = 0.0, sum2 = 0.0;
  for (int i = threadIdx.x; i < nx; i += blockDim.x) {
    const float v = sh[i].x;
    out[i] = v;
    if (better(v, y * nx + i, bv, bidx)) bv = v, bidx = y * nx + i;
    sum += v;
    sum2 += static_cast<double>(v) * v;
  }
  reduceRow(bv, bidx, sum, sum2);
  if (threadIdx.x == 0) {
    const std::size_t r = static_cast<std::size_t>(pair) * ny + y;
    p.rowMax[r] = bv, p.rowArg[r] = bidx, p.rowSum[r] = sum, p.rowSum2[r] = sum2;
  }
}

// Each pair's peak over its rows, its parabolic vertex (core's correlate: the step in [-n/2, n/2)) and its
// significance over the surface's mean and rms.
__global__ void pairPeaks(RegistrationLinkLaunch p) {
  const int pair = blockIdx.x, nx = p.x.n, ny = p.y.n;
  float bv = -INFINITY;
  int bidx = 0x7fffffff;
  double sum = 0.0, sum2 = 0.0;
  for (int r = threadIdx.x; r < ny; r += blockDim.x) {
    const std::size_t k = static_cast<std::size_t>(pair) * ny + r;
    if (better(p.rowMax[k], p.rowArg[k], bv, bidx)) bv = p.rowMax[k], bidx = p.rowArg[k];
    sum += p.rowSum[k];
    sum2 += p.rowSum2[k];
  }
  reduceRow(bv, bidx, sum, sum2);
  if (threadIdx.x != 0) return;
  double* out = p.peaks + 3 * static_cast<std::size_t>(pair);
  const float* c = p.surface + static_cast<std::size_t>(pair) * nx * ny;
  const double nr = static_cast<double>(nx) * ny;
  const double mean = sum / nr;
  const double rms = sqrt(fmax(0.0, sum2 / nr - mean * mean));
  const int px = bidx % nx, py = bidx / nx;
  const auto at = [&](int xx, int yy) {
    xx = (xx + nx) % nx;
    yy = (yy + ny) % ny;
    return static_cast<double>(c[static_cast<std::size_t>(yy) * nx + xx]);
  };
  const auto vertex = [](double m, double z, double q) {
    const double d = m - 2.0 * z + q;
    return d < 0.0 ? fmin(fmax(0.5 * (m - q) / d, -0.5), 0.5) : 0.0;
  };
  double dx = px + vertex(at(px - 1, py), at(px, py), at(px + 1, py));
  double dy = py + vertex(at(px, py - 1), at(px, py), at(px, py + 1));
  if (dx >= 0.5 * nx) dx -= nx;
  if (dy >= 0.5 * ny) dy -= ny;
  out[0] = dx;
  out[1] = dy;
  out[2] = rms > 0.0 ? (at(px, py) - mean) / rms : 0.0;
}

}  // namespace

void launchRegistrationLinks(const RegistrationLinkLaunch& p, cudaStream_t s) {
  starStats<<<static_cast<unsigned>(p.slots), kStatsThreads, 0, s>>>(p);
  checkLaunch("registration links: starStats");
  const unsigned tiles = static_cast<unsigned>((p.bw * p.bh + kThreads - 1) / kThreads);
  starImages<<<dim3(tiles, static_cast<unsigned>(p.slots)), kThreads, 0, s>>>(p);
  checkLaunch("registration links: starImages");
  const std::size_t rowBytes = static_cast<std::size_t>(p.x.n) * sizeof(float2);
  const std::size_t colBytes = 2 * static_cast<std::size_t>(p.y.n) * sizeof(float2);
  allowSharedBytes(reinterpret_cast<const void*>(&rowsForward), rowBytes, "registration link kernel");
  allowSharedBytes(reinterpret_cast<const void*>(&rowsInverse), rowBytes, "registration link kernel");
  allowSharedBytes(reinterpret_cast<const void*>(&columnsCrossCorrelation), colBytes,
                   "registration link kernel");
  rowsForward<<<dim3(static_cast<unsigned>(p.y.n), static_cast<unsigned>(p.slots)), kThreads, rowBytes, s>>>(
      p);
  checkLaunch("registration links: rowsForward");
  columnsCrossCorrelation<<<dim3(static_cast<unsigned>(p.x.n), static_cast<unsigned>(p.pairs)), kThreads,
                            colBytes, s>>>(p);
  checkLaunch("registration links: columnsCrossCorrelation");
  rowsInverse<<<dim3(static_cast<unsigned>(p.y.n), static_cast<unsigned>(p.pairs)), kThreads, rowBytes, s>>>(
      p);
  checkLaunch("registration links: rowsInverse");
  pairPeaks<<<static_cast<unsigned>(p.pairs), kThreads, 0, s>>>(p);
  checkLaunch("registration links: pairPeaks");
}

}  // namespace st::gpu

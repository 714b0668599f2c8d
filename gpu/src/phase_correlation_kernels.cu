// The sky rate's phase correlations (phase_correlation_kernels.hpp): a decimation-in-time complex FFT in
// shared memory, its input in mixed-radix digit-reversed order and its stages of radix 4, 2, 3 or 5 in
// place, one block per row or column.
#include "phase_correlation_kernels.hpp"

#include <cmath>

#include "cuda_check.hpp"
#include "phase_fft_device.cuh"

namespace st::gpu {

std::vector<int> phaseFftRadices(int n) {
  if (n < 2 || n > kMaxPhaseFftSize) return {};
  std::vector<int> r;
  int m = n;
  while (m % 4 == 0)
    r.push_back(4), m /= 4;
  for (int p : {2, 3, 5})
    while (m % p == 0)
      r.push_back(p), m /= p;
  if (m != 1) return {};
  return r;
}

std::vector<float2> phaseFftTwiddles(int n) {
  std::vector<float2> t(static_cast<std::size_t>(n));
  const double pi = 3.14159265358979323846;
  for (int k = 0; k < n; ++k) {
    const double a = -2.0 * pi * static_cast<double>(k) / n;
    t[static_cast<std::size_t>(k)] =
        make_float2(static_cast<float>(std::cos(a)), static_cast<float>(std::sin(a)));
  }
  return t;
}

namespace {

using namespace fft;

constexpr int kThreads = 256;

// Each image's rows, zero-padded, transformed along x into the spectra.
__global__ void rowsForward(PhaseCorrelationLaunch p) {
  extern __shared__ float2 sh[];
  const int y = blockIdx.x, img = blockIdx.y, nx = p.x.n, ny = p.y.n;
  float2* out = p.spectra + (static_cast<std::size_t>(img) * ny + y) * nx;
  if (y >= p.height) {
    for (int i = threadIdx.x; i < nx; i += blockDim.x)
      out[i] = make_float2(0.0f, 0.0f);
    return;
  }
  const float* in = p.images + (static_cast<std::size_t>(img) * p.height + y) * p.width;
  for (int i = threadIdx.x; i < nx; i += blockDim.x)
    sh[reversedPos(i, p.x)] = make_float2(i < p.width ? in[i] : 0.0f, 0.0f);
  __syncthreads();
  fftShared(sh, p.x, false);
  for (int i = threadIdx.x; i < nx; i += blockDim.x)
    out[i] = sh[i];
}

// Column x of a pair's two spectra transformed along y, the normalised cross-power spectrum A conj(B) / |A
// conj(B)| (detect::detail::normaliseCrossPower's double arithmetic, 0 where it vanishes), and its inverse
// transform along y, into a's spectrum.
__global__ void columnsCrossPower(PhaseCorrelationLaunch p) {
  extern __shared__ float2 sh[];
  const int x = blockIdx.x, pair = blockIdx.y, nx = p.x.n, ny = p.y.n;
  float2* sa = sh;
  float2* sb = sh + ny;
  float2* a = p.spectra + static_cast<std::size_t>(2 * pair) * nx * ny;
  const float2* b = a + static_cast<std::size_t>(nx) * ny;
  for (int i = threadIdx.x; i < ny; i += blockDim.x) {
    const int r = reversedPos(i, p.y);
    sa[r] = a[static_cast<std::size_t>(i) * nx + x];
    sb[r] = b[static_cast<std::size_t>(i) * nx + x];
  }
  __syncthreads();
  fftShared(sa, p.y, false);
  fftShared(sb, p.y, false);
  for (int i = threadIdx.x; i < ny; i += blockDim.x) {
    const float2 fa = sa[i], fb = sb[i];
    // Rounded as the CPU's loop rounds (no contraction into fused multiply-adds).
    const double re = __dadd_rn(__dmul_rn(fa.x, fb.x), __dmul_rn(fa.y, fb.y));
    const double im = __dsub_rn(__dmul_rn(fa.y, fb.x), __dmul_rn(fa.x, fb.y));
    const double m = sqrt(__dadd_rn(__dmul_rn(re, re), __dmul_rn(im, im)));
    sb[i] = m > 0.0 ? make_float2(static_cast<float>(re / m), static_cast<float>(im / m))
                    : make_float2(0.0f, 0.0f);
  }
  __syncthreads();
  for (int i = threadIdx.x; i < ny; i += blockDim.x)
    sa[reversedPos(i, p.y)] = sb[i];
  __syncthreads();
  fftShared(sa, p.y, true);
  for (int i = threadIdx.x; i < ny; i += blockDim.x)
    a[static_cast<std::size_t>(i) * nx + x] = sa[i];
}

// The better of two candidates for the peak: the larger value, of equal ones the smaller index in the
// quadrant-swapped row order (detect::detail::firstLargestShifted).
__device__ __forceinline__ bool better(float v, int idx, float bv, int bidx) {
  return v > bv || (v == bv && idx < bidx);
}

// Block-wide reduction of (value, index) pairs and an all-finite flag; the result is valid in thread 0.
__device__ void reducePeak(float& v, int& idx, int& finite) {
  __shared__ float rv[kThreads];
  __shared__ int ri[kThreads];
  __shared__ int rf[kThreads];
  rv[threadIdx.x] = v;
  ri[threadIdx.x] = idx;
  rf[threadIdx.x] = finite;
  __syncthreads();
  for (int half = blockDim.x / 2; half > 0; half /= 2) {
    if (threadIdx.x < half) {
      const int o = threadIdx.x + half;
      if (better(rv[o], ri[o], rv[threadIdx.x], ri[threadIdx.x]))
        rv[threadIdx.x] = rv[o], ri[threadIdx.x] = ri[o];
      rf[threadIdx.x] &= rf[o];
    }
    __syncthreads();
  }
  v = rv[0];
  idx = ri[0];
  finite = rf[0];
}

// Row y of a pair's cross-power spectrum transformed back along x: its real part is the surface's row (the
// transform unscaled, as FFTW's c2r). Each row's peak and whether it was all finite.
__global__ void rowsInverse(PhaseCorrelationLaunch p) {
  extern __shared__ float2 sh[];
  const int y = blockIdx.x, pair = blockIdx.y, nx = p.x.n, ny = p.y.n;
  const float2* in = p.spectra + (static_cast<std::size_t>(2 * pair) * ny + y) * nx;
  for (int i = threadIdx.x; i < nx; i += blockDim.x)
    sh[reversedPos(i, p.x)] = in[i];
  __syncthreads();
  fftShared(sh, p.x, true);
  float* out = p.surface + (static_cast<std::size_t>(pair) * ny + y) * nx;
  const int rowShifted = ((y + ny / 2) % ny) * nx;
  float bv = -INFINITY;
  int bidx = 0x7fffffff, finite = 1;
  for (int i = threadIdx.x; i < nx; i += blockDim.x) {
    const float v = sh[i].x;
    out[i] = v;
    if (!isfinite(v)) {
      finite = 0;
      continue;
    }
    const int idx = rowShifted + (i + nx / 2) % nx;
    if (better(v, idx, bv, bidx)) bv = v, bidx = idx;
  }
  reducePeak(bv, bidx, finite);
  if (threadIdx.x == 0) {
    p.rowMax[static_cast<std::size_t>(pair) * ny + y] = bv;
    p.rowArg[static_cast<std::size_t>(pair) * ny + y] = finite ? bidx : -1;
  }
}

// Each pair's peak over its rows and the 5 x 5 centroid around it (detect::detail::phaseShift's double
// arithmetic and order): the offset from the centre and the summed peak / (nx ny) as the response.
__global__ void pairPeaks(PhaseCorrelationLaunch p) {
  const int pair = blockIdx.x, nx = p.x.n, ny = p.y.n;
  float bv = -INFINITY;
  int bidx = 0x7fffffff, finite = 1;
  for (int r = threadIdx.x; r < ny; r += blockDim.x) {
    const float v = p.rowMax[static_cast<std::size_t>(pair) * ny + r];
    const int idx = p.rowArg[static_cast<std::size_t>(pair) * ny + r];
    if (idx < 0) {
      finite = 0;
      continue;
    }
    if (better(v, idx, bv, bidx)) bv = v, bidx = idx;
  }
  reducePeak(bv, bidx, finite);
  if (threadIdx.x != 0) return;
  double* out = p.peaks + 4 * static_cast<std::size_t>(pair);
  if (!finite || bidx == 0x7fffffff) {
    out[0] = out[1] = out[2] = out[3] = 0.0;
    return;
  }
  const float* c = p.surface + static_cast<std::size_t>(pair) * nx * ny;
  const int xFrom = nx - nx / 2, yFrom = ny - ny / 2;
  const int px = bidx % nx, py = bidx / nx;
  double sx = 0.0, sy = 0.0, sum = 0.0;
  for (int yy = max(0, py - 2); yy <= min(ny - 1, py + 2); ++yy)
    for (int xx = max(0, px - 2); xx <= min(nx - 1, px + 2); ++xx) {
      const double v = c[static_cast<std::size_t>((yy + yFrom) % ny) * nx + (xx + xFrom) % nx];
      sx = __dadd_rn(sx, __dmul_rn(xx, v));
      sy = __dadd_rn(sy, __dmul_rn(yy, v));
      sum = __dadd_rn(sum, v);
    }
  out[2] = sum / (static_cast<double>(nx) * ny);
  sum = __dadd_rn(sum, 2.220446049250313e-16);
  out[0] = __dsub_rn(__dmul_rn(0.5, nx), sx / sum);
  out[1] = __dsub_rn(__dmul_rn(0.5, ny), sy / sum);
  out[3] = 1.0;
}

}  // namespace

void launchPhaseCorrelation(const PhaseCorrelationLaunch& p, cudaStream_t s) {
  const std::size_t rowBytes = static_cast<std::size_t>(p.x.n) * sizeof(float2);
  const std::size_t colBytes = 2 * static_cast<std::size_t>(p.y.n) * sizeof(float2);
  allowSharedBytes(reinterpret_cast<const void*>(&rowsForward), rowBytes, "phase correlation kernel");
  allowSharedBytes(reinterpret_cast<const void*>(&rowsInverse), rowBytes, "phase correlation kernel");
  allowSharedBytes(reinterpret_cast<const void*>(&columnsCrossPower), colBytes, "phase correlation kernel");
  rowsForward<<<dim3(static_cast<unsigned>(p.y.n), static_cast<unsigned>(2 * p.pairs)), kThreads, rowBytes,
                s>>>(p);
  checkLaunch("phase correlation: rowsForward");
  columnsCrossPower<<<dim3(static_cast<unsigned>(p.x.n), static_cast<unsigned>(p.pairs)), kThreads, colBytes,
                      s>>>(p);
  checkLaunch("phase correlation: columnsCrossPower");
  rowsInverse<<<dim3(static_cast<unsigned>(p.y.n), static_cast<unsigned>(p.pairs)), kThreads, rowBytes, s>>>(
      p);
  checkLaunch("phase correlation: rowsInverse");
  pairPeaks<<<static_cast<unsigned>(p.pairs), kThreads, 0, s>>>(p);
  checkLaunch("phase correlation: pairPeaks");
}

}  // namespace st::gpu

// Kernels of zero_bias_kernels.hpp: star subtraction and the zeroing stages on a cube kept on the device.
// The star template's arithmetic is the CPU's (core/detect/star_subtraction.cpp) operation by operation in
// double without fused multiply-adds (__dmul_rn/__dadd_rn), the per-block sums in float in the CPU's frame
// order, so templates and subtracted pixels are the CPU's; the residual variance sums per position run over
// the frames in order (the CPU adds its threads' partial sums in a varying order: rounding only).
#include <cstdint>

#include "cuda_check.hpp"
#include "zero_bias_kernels.hpp"

namespace st::gpu {
namespace {

constexpr int kThreads = 128;

unsigned blocksFor(std::size_t n, int threads = kThreads) {
  const std::size_t b = (n + threads - 1) / threads;
  return static_cast<unsigned>(b < 1 ? 1 : (b > 2147483647u ? 2147483647u : b));
}

__global__ void __launch_bounds__(kThreads) starTemplateKernel(StarTemplateLaunch p) {
  const int k = blockIdx.x * blockDim.x + threadIdx.x;
  const int b = blockIdx.y;
  if (k >= p.np) return;
  const int pos = p.positions[k];
  const int bx = p.x0 + pos % p.cw, by = p.y0 + pos / p.cw;
  const std::size_t fp = static_cast<std::size_t>(p.width) * p.height;
  float sum = 0.0f, cnt = 0.0f;
  for (int e = p.blockStart[b]; e < p.blockStart[b + 1]; ++e) {
    const int n = p.blockFrames[e];
    const int x = bx + p.lz.sx[n] + p.lz.ox[n], y = by + p.lz.sy[n] + p.lz.oy[n];
    if (x < 0 || y < 0 || x + 5 >= p.width || y + 5 >= p.height) continue;
    const float* f = p.pix + static_cast<std::size_t>(n) * fp;
    const std::uint8_t* m = p.mask ? p.mask + static_cast<std::size_t>(n) * fp : nullptr;
    const double* wx = p.lz.wx + 6 * n;
    const double* wy = p.lz.wy + 6 * n;
    double v = 0.0;
    bool bad = false;
    for (int j = 0; j < 6 && !bad; ++j) {
      const std::size_t row = static_cast<std::size_t>(y + j) * p.width;
      double r = 0.0;
      for (int i = 0; i < 6; ++i) {
        const std::size_t q = row + x + i;
        if (m && m[q]) {
          bad = true;
          break;
        }
        r = __dadd_rn(r, __dmul_rn(wx[i], static_cast<double>(f[q])));
      }
      v = __dadd_rn(v, __dmul_rn(wy[j], r));
    }
    if (bad) continue;
    sum = __fadd_rn(sum, __double2float_rn(v));
    cnt = __fadd_rn(cnt, 1.0f);
  }
  p.sum[static_cast<std::size_t>(b) * p.np + k] = sum;
  p.cnt[static_cast<std::size_t>(b) * p.np + k] = cnt;
}

__global__ void __launch_bounds__(kThreads)
    starTemplateBuildKernel(const float* sum, const float* cnt, int np, int nb, const std::uint8_t* excluded,
                            const int* positions, std::size_t canvasSize, double minFrames, float* tmpl,
                            std::uint8_t* valid, unsigned long long* framesSum, unsigned long long* framesN) {
  const int k = blockIdx.x * blockDim.x + threadIdx.x;
  const int b = blockIdx.y;
  bool kept = false;
  unsigned long long frames = 0;
  if (k < np) {
    double sv = 0.0, c = 0.0;
    for (int o = 0; o < nb; ++o)
      if (!excluded[b * nb + o]) {
        sv = __dadd_rn(sv, static_cast<double>(sum[static_cast<std::size_t>(o) * np + k]));
        c = __dadd_rn(c, static_cast<double>(cnt[static_cast<std::size_t>(o) * np + k]));
      }
    if (c >= minFrames) {
      const std::size_t at = static_cast<std::size_t>(b) * canvasSize + positions[k];
      tmpl[at] = __double2float_rn(__ddiv_rn(sv, c));
      valid[at] = 1;
      kept = true;
      frames = static_cast<unsigned long long>(c);  // a whole number of frames
    }
  }
  for (int o = 16; o > 0; o >>= 1)
    frames += __shfl_down_sync(0xffffffffu, frames, o);
  const unsigned ballot = __ballot_sync(0xffffffffu, kept);
  if ((threadIdx.x & 31) == 0 && ballot) {
    atomicAdd(framesSum, frames);
    atomicAdd(framesN, static_cast<unsigned long long>(__popc(ballot)));
  }
}

__global__ void __launch_bounds__(kThreads) starSubtractKernel(StarSubtractLaunch p) {
  const int k = blockIdx.x * blockDim.x + threadIdx.x;
  unsigned long long subtracted = 0, zeroed = 0;
  if (k < p.nt) {
    const int i = p.targets[k] % p.cw, j = p.targets[k] / p.cw;
    const std::size_t fp = static_cast<std::size_t>(p.width) * p.height;
    const std::size_t canvas = static_cast<std::size_t>(p.cw) * p.ch;
    double r2 = 0.0, s2 = 0.0;
    float samples = 0.0f;
    for (int n = 0; n < p.nf; ++n) {
      const int x = p.x0 + i + p.lz.sx[n], y = p.y0 + j + p.lz.sy[n];
      if (x < 0 || y < 0 || x >= p.width || y >= p.height) continue;
      const std::size_t at = static_cast<std::size_t>(y) * p.width + x;
      float* px = p.pix + static_cast<std::size_t>(n) * fp + at;
      const int ox = p.lz.ox[n], oy = p.lz.oy[n];
      bool bad = i + ox < 0 || j + oy < 0 || i + ox + 5 >= p.cw || j + oy + 5 >= p.ch;
      const int b = p.blockOf[n];
      const float* t = p.tmpl + static_cast<std::size_t>(b) * canvas;
      const std::uint8_t* ok = p.valid + static_cast<std::size_t>(b) * canvas;
      const double* wx = p.lz.wx + 6 * n;
      const double* wy = p.lz.wy + 6 * n;
      double v = 0.0;
      for (int jj = 0; jj < 6 && !bad; ++jj) {
        const std::size_t row = static_cast<std::size_t>(j + oy + jj) * p.cw;
        double r = 0.0;
        for (int ii = 0; ii < 6; ++ii) {
          const std::size_t q = row + i + ox + ii;
          if (!ok[q]) {
            bad = true;
            break;
          }
          r = __dadd_rn(r, __dmul_rn(wx[ii], static_cast<double>(t[q])));
        }
        v = __dadd_rn(v, __dmul_rn(wy[jj], r));
      }
      float value = *px;
      if (bad) {
        if (value != 0.0f) ++zeroed;
        *px = 0.0f;
        continue;
      }
      value = __fsub_rn(value, __double2float_rn(v));
      *px = value;
      ++subtracted;
      if (p.sigma && value != 0.0f) {
        const double sg = p.sigma[at];
        if (sg > 0) {
          r2 = __dadd_rn(r2, __dmul_rn(static_cast<double>(value), static_cast<double>(value)));
          s2 = __dadd_rn(s2, __dmul_rn(sg, sg));
          samples = __fadd_rn(samples, 1.0f);
        }
      }
    }
    if (p.sigma) {
      p.r2[k] = r2;
      p.s2[k] = s2;
      p.samples[k] = samples;
    }
  }
  // Integer counts: any order gives the same totals.
  for (int o = 16; o > 0; o >>= 1) {
    subtracted += __shfl_down_sync(0xffffffffu, subtracted, o);
    zeroed += __shfl_down_sync(0xffffffffu, zeroed, o);
  }
  if ((threadIdx.x & 31) == 0) {
    if (subtracted) atomicAdd(p.counts, subtracted);
    if (zeroed) atomicAdd(p.counts + 1, zeroed);
  }
}

__global__ void whitenKernel(float* pix, int width, int height, int nf, const int* positions,
                             const float* factors, int count, int cw, int x0, int y0, const int* sx,
                             const int* sy) {
  const std::size_t t = static_cast<std::size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (t >= static_cast<std::size_t>(count) * nf) return;
  const int e = static_cast<int>(t % count), n = static_cast<int>(t / count);
  const int x = x0 + positions[e] % cw + sx[n], y = y0 + positions[e] / cw + sy[n];
  if (x < 0 || y < 0 || x >= width || y >= height) return;
  float& v = pix[static_cast<std::size_t>(n) * width * height + static_cast<std::size_t>(y) * width + x];
  v = __fmul_rn(v, factors[e]);
}

__global__ void zeroIndicesKernel(float* pix, std::size_t total, const std::uint64_t* idx,
                                  std::size_t count) {
  const std::size_t t = static_cast<std::size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (t < count && idx[t] < total) pix[idx[t]] = 0.0f;
}

__device__ void addCount(bool flag, unsigned long long* counter) {
  const unsigned ballot = __ballot_sync(0xffffffffu, flag);
  if ((threadIdx.x & 31) == 0 && ballot) atomicAdd(counter, static_cast<unsigned long long>(__popc(ballot)));
}

__global__ void zeroMaskedKernel(float* pix, int width, int height, int nf, const int* xy, int count,
                                 const int* sx, const int* sy, unsigned long long* zeroed) {
  const std::size_t t = static_cast<std::size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  bool inside = false;
  if (t < static_cast<std::size_t>(count) * nf) {
    const int e = static_cast<int>(t % count), n = static_cast<int>(t / count);
    const int x = xy[2 * e] + sx[n], y = xy[2 * e + 1] + sy[n];
    if (x >= 0 && y >= 0 && x < width && y < height) {
      pix[static_cast<std::size_t>(n) * width * height + static_cast<std::size_t>(y) * width + x] = 0.0f;
      inside = true;
    }
  }
  addCount(inside, zeroed);
}

__global__ void zeroUnmeasuredKernel(float* pix, std::size_t fp, int nf, const int* pixels, int count,
                                     unsigned long long* zeroed) {
  const int t = blockIdx.x * blockDim.x + threadIdx.x;
  bool any = false;
  if (t < count) {
    float* v = pix + pixels[t];
    for (int n = 0; n < nf; ++n, v += fp) {
      any |= *v != 0.0f;
      *v = 0.0f;
    }
  }
  addCount(any, zeroed);
}

__global__ void singleFrameSeedsKernel(SingleFrameLaunch p) {
  const std::size_t fp = static_cast<std::size_t>(p.width) * p.height;
  const std::size_t total = fp * p.nf;
  for (std::size_t t = static_cast<std::size_t>(blockIdx.x) * blockDim.x + threadIdx.x; t < total;
       t += static_cast<std::size_t>(gridDim.x) * blockDim.x) {
    const std::size_t i = t % fp;
    const int n = static_cast<int>(t / fp);
    const double s = p.sigma ? static_cast<double>(p.sigma[i]) : p.sigmaN;
    if (s <= 0 || static_cast<double>(p.pix[t]) < __dmul_rn(p.snr, s)) continue;
    if (p.keepCanvas) {
      const int ci = static_cast<int>(i % p.width) - p.keepSx[n] - p.keepX0;
      const int cj = static_cast<int>(i / p.width) - p.keepSy[n] - p.keepY0;
      if (ci >= 0 && cj >= 0 && ci < p.keepCw && cj < p.keepCh &&
          p.keepCanvas[static_cast<std::size_t>(cj) * p.keepCw + ci])
        continue;
    }
    const unsigned long long slot = atomicAdd(p.seedCount, 1ull);
    if (slot < p.seedCap) p.seeds[slot] = t;
    atomicAdd(p.seedsPerFrame + n, 1ull);
  }
}

__global__ void singleFrameZeroKernel(SingleFrameLaunch p, unsigned long long seeds) {
  const int d = 2 * p.radius + 1;
  const std::size_t t = static_cast<std::size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (t >= seeds * d * d) return;
  const std::size_t fp = static_cast<std::size_t>(p.width) * p.height;
  const std::uint64_t seed = p.seeds[t / (d * d)];
  const int o = static_cast<int>(t % (d * d));
  const int dx = o % d - p.radius, dy = o / d - p.radius;
  const std::size_t n = seed / fp, i = seed % fp;
  const int x = static_cast<int>(i % p.width) + dx, y = static_cast<int>(i / p.width) + dy;
  if (x < 0 || y < 0 || x >= p.width || y >= p.height || dx * dx + dy * dy > p.radius * p.radius) return;
  float* v = p.pix + n * fp + static_cast<std::size_t>(y) * p.width + x;
  // Zeroed once whichever seed's disc gets there first; counted only where it was not 0 (the CPU's test).
  const float old = __int_as_float(atomicExch(reinterpret_cast<int*>(v), 0));
  if (old != 0.0f) atomicAdd(p.zeroedPerFrame + n, 1ull);
}

constexpr int kMedianThreads = 1024;

__device__ __forceinline__ bool frameSample(const float* f, const float* var, std::size_t i, double* r) {
  const float x = f[i], v = var[i];
  if (!(x != 0.0f && v > 0.0f && isfinite(x))) return false;
  *r = __ddiv_rn(__dmul_rn(static_cast<double>(x), static_cast<double>(x)), static_cast<double>(v));
  return true;
}

// One block per frame: the count, then 8 passes of an 8-bit radix select from the top byte.
__global__ void __launch_bounds__(kMedianThreads)
    frameMedianKernel(const float* pix, const float* var, std::size_t np, int stride, double* median,
                      unsigned* count) {
  __shared__ unsigned hist[256];
  __shared__ unsigned total;
  __shared__ unsigned long long prefix;
  __shared__ unsigned rank;
  const int n = blockIdx.x;
  const float* f = pix + static_cast<std::size_t>(n) * np;
  const std::size_t first = static_cast<std::size_t>(n % stride), step = static_cast<std::size_t>(stride);
  if (threadIdx.x == 0) {
    total = 0;
    prefix = 0;
  }
  __syncthreads();
  unsigned c = 0;
  for (std::size_t i = first + threadIdx.x * step; i < np; i += blockDim.x * step) {
    double r;
    c += frameSample(f, var, i, &r);
  }
  atomicAdd(&total, c);
  __syncthreads();
  if (threadIdx.x == 0) {
    count[n] = total;
    rank = total / 2;
  }
  if (total == 0) {
    if (threadIdx.x == 0) median[n] = 0.0;
    return;
  }
  for (int shift = 56; shift >= 0; shift -= 8) {
    for (int b = threadIdx.x; b < 256; b += blockDim.x)
      hist[b] = 0;
    __syncthreads();
    const unsigned long long high = shift == 56 ? 0ull : ~0ull << (shift + 8);
    const unsigned long long want = prefix;
    for (std::size_t i = first + threadIdx.x * step; i < np; i += blockDim.x * step) {
      double r;
      if (!frameSample(f, var, i, &r)) continue;
      const unsigned long long key = static_cast<unsigned long long>(__double_as_longlong(r));
      if ((key & high) == want) atomicAdd(&hist[(key >> shift) & 255u], 1u);
    }
    __syncthreads();
    if (threadIdx.x == 0) {
      unsigned k = rank;
      int b = 0;
      for (; b < 255 && k >= hist[b]; ++b)
        k -= hist[b];
      prefix = want | (static_cast<unsigned long long>(b) << shift);
      rank = k;
    }
    __syncthreads();
  }
  if (threadIdx.x == 0) median[n] = __longlong_as_double(static_cast<long long>(prefix));
}

}  // namespace

void launchFrameMedians(const float* pix, const float* variance, std::size_t framePixels, int nf, int stride,
                        double* median, unsigned* count, cudaStream_t s) {
  if (nf <= 0) return;
  frameMedianKernel<<<nf, kMedianThreads, 0, s>>>(pix, variance, framePixels, stride < 1 ? 1 : stride, median,
                                                  count);
  checkLaunch("frameMedianKernel");
}

void launchStarTemplateSums(const StarTemplateLaunch& p, cudaStream_t s) {
  if (p.np <= 0 || p.nb <= 0) return;
  starTemplateKernel<<<dim3(blocksFor(p.np), p.nb), kThreads, 0, s>>>(p);
  checkLaunch("starTemplateKernel");
}

void launchStarTemplateBuild(const float* sum, const float* cnt, int np, int nb, const std::uint8_t* excluded,
                             const int* positions, std::size_t canvasSize, double minFrames, float* tmpl,
                             std::uint8_t* valid, unsigned long long* framesSum, unsigned long long* framesN,
                             cudaStream_t s) {
  if (np <= 0 || nb <= 0) return;
  starTemplateBuildKernel<<<dim3(blocksFor(np), nb), kThreads, 0, s>>>(
      sum, cnt, np, nb, excluded, positions, canvasSize, minFrames, tmpl, valid, framesSum, framesN);
  checkLaunch("starTemplateBuildKernel");
}

void launchStarSubtract(const StarSubtractLaunch& p, cudaStream_t s) {
  if (p.nt <= 0) return;
  starSubtractKernel<<<blocksFor(p.nt), kThreads, 0, s>>>(p);
  checkLaunch("starSubtractKernel");
}

void launchWhiten(float* pix, int width, int height, int nf, const int* positions, const float* factors,
                  int count, int cw, int x0, int y0, const int* sx, const int* sy, cudaStream_t s) {
  if (count <= 0 || nf <= 0) return;
  whitenKernel<<<blocksFor(static_cast<std::size_t>(count) * nf, 256), 256, 0, s>>>(
      pix, width, height, nf, positions, factors, count, cw, x0, y0, sx, sy);
  checkLaunch("whitenKernel");
}

void launchZeroIndices(float* pix, std::size_t total, const std::uint64_t* idx, std::size_t count,
                       cudaStream_t s) {
  if (count == 0) return;
  zeroIndicesKernel<<<blocksFor(count, 256), 256, 0, s>>>(pix, total, idx, count);
  checkLaunch("zeroIndicesKernel");
}

void launchZeroMasked(float* pix, int width, int height, int nf, const int* xy, int count, const int* sx,
                      const int* sy, unsigned long long* zeroed, cudaStream_t s) {
  if (count <= 0 || nf <= 0) return;
  zeroMaskedKernel<<<blocksFor(static_cast<std::size_t>(count) * nf, 256), 256, 0, s>>>(
      pix, width, height, nf, xy, count, sx, sy, zeroed);
  checkLaunch("zeroMaskedKernel");
}

void launchZeroUnmeasured(float* pix, std::size_t framePixels, int nf, const int* pixels, int count,
                          unsigned long long* zeroed, cudaStream_t s) {
  if (count <= 0) return;
  zeroUnmeasuredKernel<<<blocksFor(count, 256), 256, 0, s>>>(pix, framePixels, nf, pixels, count, zeroed);
  checkLaunch("zeroUnmeasuredKernel");
}

void launchSingleFrameSeeds(const SingleFrameLaunch& p, cudaStream_t s) {
  singleFrameSeedsKernel<<<132 * 16, 256, 0, s>>>(p);
  checkLaunch("singleFrameSeedsKernel");
}

void launchSingleFrameZero(const SingleFrameLaunch& p, unsigned long long seeds, cudaStream_t s) {
  const int d = 2 * p.radius + 1;
  if (seeds == 0) return;
  singleFrameZeroKernel<<<blocksFor(seeds * d * d, 256), 256, 0, s>>>(p, seeds);
  checkLaunch("singleFrameZeroKernel");
}

}  // namespace st::gpu

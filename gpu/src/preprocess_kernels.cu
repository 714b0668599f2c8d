// Pre-processing kernels (issue 16): the per-pixel background of stats::subtractPixelBackground and the
// matched filter of stack::filterCube. The clip and the subtraction run one thread per pixel over the frames
// in the CPU's order with the CPU's double arithmetic (no fused multiply-adds: __dmul_rn/__dadd_rn), so
// their results are the CPU's bit for bit; the convolution is a direct sum in float, where the CPU's is an
// FFT (float tolerance: tests/gpu GpuFilter.MatchesCpu).
#include <cmath>
#include <cstdint>
#include <cstdlib>

#include "cuda_check.hpp"
#include "preprocess_params.hpp"

namespace st::gpu {
namespace {

constexpr int kTileX = 32;
constexpr int kTileY = 8;
__constant__ float c_filter[(2 * kMaxFilterHalf + 1) * (2 * kMaxFilterHalf + 1)];

__device__ __forceinline__ bool covered(const BackgroundLaunch& p, int n, int x, int y) {
  if (!p.canvas) return false;
  const int cx = x - p.canvasShiftX[n] - p.canvasX0;
  const int cy = y - p.canvasShiftY[n] - p.canvasY0;
  if (cx < 0 || cy < 0 || cx >= p.canvasW || cy >= p.canvasH) return false;
  return p.canvas[static_cast<std::size_t>(cy) * p.canvasW + cx] != 0;
}

__global__ void backgroundPrepareKernel(BackgroundLaunch p) {
  const std::size_t np = static_cast<std::size_t>(p.width) * p.height;
  const std::size_t i = blockIdx.x * static_cast<std::size_t>(blockDim.x) + threadIdx.x;
  const int k = blockIdx.y;
  if (i >= np || k >= p.nk) return;
  const int n = p.usedFrames[k];
  const std::size_t off = static_cast<std::size_t>(n) * np + i;
  const float v = p.pix[off];
  const int x = static_cast<int>(i % p.width), y = static_cast<int>(i / p.width);
  const bool out = !isfinite(v) || (p.mask && p.mask[off]) || covered(p, n, x, y);
  p.buf[static_cast<std::size_t>(k) * np + i] = out ? __int_as_float(0x7fc00000) : v;
}

// Floats in the order of unsigned keys (NaN left out by the callers).
__device__ __forceinline__ unsigned floatKey(float v) {
  const unsigned b = __float_as_uint(v);
  return (b & 0x80000000u) ? ~b : (b | 0x80000000u);
}

__device__ __forceinline__ float keyFloat(unsigned k) {
  return __uint_as_float((k & 0x80000000u) ? (k & 0x7fffffffu) : ~k);
}

// stats/strong_signal_cut.cpp cutStrongAboveMedian for one pixel: the lower median (element (c - 1) / 2 in
// order of the c samples left in, the value std::nth_element gives: the smallest float key with at least
// (c - 1) / 2 + 1 samples at or below it) by bisection over the float keys between the smallest and the
// largest sample's (the counting pass finds them: ~23 passes on sky values instead of 32, each counting the
// samples at or below the middle key), then the samples above median + strongOffset (in double) become NaN.
// A 16-way search (8 passes of 15 pivots) was slower: 14.9 against 12.6 ms on the paper's cube (H200,
// 2026-12-03), the passes' compares and not their loads being the cost.
__global__ void backgroundStrongCutKernel(BackgroundLaunch p) {
  const std::size_t np = static_cast<std::size_t>(p.width) * p.height;
  const std::size_t i = blockIdx.x * static_cast<std::size_t>(blockDim.x) + threadIdx.x;
  if (i >= np) return;
  float* b = p.buf + i;
  unsigned c = 0, lo = 0xffffffffu, hi = 0u;
  for (int k = 0; k < p.nk; ++k) {
    const float v = b[static_cast<std::size_t>(k) * np];
    if (isnan(v)) continue;
    const unsigned key = floatKey(v);
    ++c;
    lo = min(lo, key);
    hi = max(hi, key);
  }
  if (c == 0) return;
  const unsigned rank = (c - 1) / 2 + 1;  // the smallest key with at least this many samples at or below it
  while (lo < hi) {
    const unsigned mid = lo + (hi - lo) / 2;
    unsigned below = 0;
    for (int k = 0; k < p.nk; ++k) {
      const float v = b[static_cast<std::size_t>(k) * np];
      below += (!isnan(v) && floatKey(v) <= mid) ? 1u : 0u;
    }
    if (below >= rank)
      hi = mid;
    else
      lo = mid + 1;
  }
  const double cut = __dadd_rn(static_cast<double>(keyFloat(lo)), p.strongOffset);
  for (int k = 0; k < p.nk; ++k) {
    float* q = b + static_cast<std::size_t>(k) * np;
    if (static_cast<double>(*q) > cut) *q = __int_as_float(0x7fc00000);
  }
}

// stats/background.cpp clipRow for one pixel.
__global__ void backgroundClipKernel(BackgroundLaunch p) {
  const std::size_t np = static_cast<std::size_t>(p.width) * p.height;
  const std::size_t i = blockIdx.x * static_cast<std::size_t>(blockDim.x) + threadIdx.x;
  if (i >= np) return;
  const float* b = p.buf + i;
  double shift = 0.0, mean = 0.0, sig = 0.0, hi = INFINITY;
  std::size_t count = 0, prev = static_cast<std::size_t>(-1);
  bool done = true;
  for (int k = 0; k < p.nk; ++k) {
    const float v = b[static_cast<std::size_t>(k) * np];
    if (!isnan(v)) {
      shift = v;
      done = false;
      break;
    }
  }
  for (int it = 0; it < 100 && !done; ++it) {
    double s = 0.0, ss = 0.0;
    std::size_t c = 0;
    for (int k = 0; k < p.nk; ++k) {
      const double y = b[static_cast<std::size_t>(k) * np];
      if (!(y <= hi)) continue;
      const double d = __dsub_rn(y, shift);
      ++c;
      s = __dadd_rn(s, d);
      ss = __dadd_rn(ss, __dmul_rn(d, d));
    }
    count = c;
    if (c == 0) break;
    const double m = s / static_cast<double>(c);
    mean = __dadd_rn(shift, m);
    sig = c > 1 ? sqrt(fmax(0.0, __dsub_rn(ss, __dmul_rn(s, m)) / static_cast<double>(c - 1))) : 0.0;
    if (c == prev) break;
    prev = c;
    hi = __dadd_rn(mean, __dmul_rn(p.xi, sig));
  }
  const bool ok = count >= p.minSamples;
  p.valid[i] = ok ? 1 : 0;
  p.level[i] = static_cast<float>(ok ? mean : p.globalMean);
  p.sigma[i] = static_cast<float>(ok ? sig : p.globalSigma);
  p.hi[i] = hi;
}

// stats/background.cpp subtractPixelBackground's onRow for one pixel: running window sums in the CPU's order.
__global__ void backgroundSubtractKernel(BackgroundLaunch p) {
  const std::size_t np = static_cast<std::size_t>(p.width) * p.height;
  const std::size_t i = blockIdx.x * static_cast<std::size_t>(blockDim.x) + threadIdx.x;
  if (i >= np) return;
  const float* b = p.buf + i;
  const double hi = p.hi[i];
  double total = 0.0, winS = 0.0;
  std::size_t totalC = 0, winC = 0;
  for (int k = 0; k < p.nk; ++k) {
    const float v = b[static_cast<std::size_t>(k) * np];
    if (!isnan(v) && v <= hi) {
      total = __dadd_rn(total, static_cast<double>(v));
      ++totalC;
    }
  }
  const bool validPx = p.valid[i] != 0;
  const float levelPx = p.level[i];
  const std::size_t need3 = totalC / 3 > 4 ? totalC / 3 : 4;
  const std::size_t need = p.minSamples < need3 ? p.minSamples : need3;
  int curLo = 0, curHi = 0;
  for (int n = 0; n < p.nf; ++n) {
    if (p.window) {
      for (; curHi < p.winHi[n]; ++curHi) {
        const float v = b[static_cast<std::size_t>(curHi) * np];
        if (!isnan(v) && v <= hi) {
          winS = __dadd_rn(winS, static_cast<double>(v));
          ++winC;
        }
      }
      for (; curLo < p.winLo[n]; ++curLo) {
        const float v = b[static_cast<std::size_t>(curLo) * np];
        if (!isnan(v) && v <= hi) {
          winS = __dsub_rn(winS, static_cast<double>(v));
          --winC;
        }
      }
    }
    const std::size_t c = totalC - winC;
    const float level =
        validPx && c >= need ? static_cast<float>(__dsub_rn(total, winS) / static_cast<double>(c)) : levelPx;
    const std::size_t off = static_cast<std::size_t>(n) * np + i;
    const float v = __fsub_rn(p.pix[off], level);
    p.pix[off] = ((p.mask && p.mask[off]) || !isfinite(v)) ? 0.0f : v;
  }
}

// The filter's tile of frame f0 + blockIdx.z: the input's pixels [x0, x0 + tw) x [y0, y0 + th) row by row
// (0 outside the frame, where masked and where not finite; times the weight where weighted), by every thread
// of the block, then a barrier.
__device__ __forceinline__ void loadFilterTile(const FilterLaunch& p, float* tile, int x0, int y0, int tw,
                                               int th) {
  const int n = p.f0 + static_cast<int>(blockIdx.z);
  const std::size_t base = static_cast<std::size_t>(n) * p.width * p.height;
  const float invS2 = p.invVar ? p.invS2[n] : 1.0f;
  const int threads = static_cast<int>(blockDim.x * blockDim.y);
  for (int t = static_cast<int>(threadIdx.y * blockDim.x + threadIdx.x); t < tw * th; t += threads) {
    const int gx = x0 + t % tw, gy = y0 + t / tw;
    float v = 0.0f;
    if (gx >= 0 && gy >= 0 && gx < p.width && gy < p.height) {
      const std::size_t q = static_cast<std::size_t>(gy) * p.width + gx;
      v = p.in[base + q];
      if (!isfinite(v) || (p.mask && p.mask[base + q])) v = 0.0f;
      if (p.invVar) v = __fmul_rn(v, __fmul_rn(p.invVar[q], invS2));
    }
    tile[t] = v;
  }
  __syncthreads();
}

__global__ void filterKernel(FilterLaunch p) {
  extern __shared__ float tile[];
  const int K = 2 * p.half + 1;
  const int tw = kTileX + 2 * p.half, th = kTileY + 2 * p.half;
  const std::size_t np = static_cast<std::size_t>(p.width) * p.height;
  const std::size_t base = static_cast<std::size_t>(p.f0 + static_cast<int>(blockIdx.z)) * np;
  loadFilterTile(p, tile, blockIdx.x * kTileX - p.half, blockIdx.y * kTileY - p.half, tw, th);
  const int x = blockIdx.x * kTileX + threadIdx.x, y = blockIdx.y * kTileY + threadIdx.y;
  if (x >= p.width || y >= p.height) return;
  float acc = 0.0f;
  for (int dy = 0; dy < K; ++dy) {
    const float* row = tile + (threadIdx.y + dy) * tw + threadIdx.x;
    const float* krow = c_filter + dy * K;
    for (int dx = 0; dx < K; ++dx)
      acc = fmaf(krow[dx], row[dx], acc);
  }
  const std::size_t q = static_cast<std::size_t>(y) * p.width + x;
  if (p.outScale) acc = __fmul_rn(acc, p.outScale[q]);
  p.out[base + q] = acc;
}

// The filter with 4 adjacent outputs a thread along x (issue 16: 3x fewer shared-memory loads a product than
// filterKernel's one output a thread): each thread reads its row window as float4s once per kernel row and
// keeps it in registers. Every output's products are summed in filterKernel's order (kernel rows, then
// columns, ascending; one fmaf each), so the two give the same bits.
constexpr int kX4Outputs = 4;
constexpr int kX4TileX = 32 * kX4Outputs;  // outputs a block along x
constexpr int kX4TileY = 8;

template <int H>
constexpr int x4TileWidth() {  // the tile's row pitch: every float4 of every window inside, a multiple of 4
  return (kX4TileX + 2 * H + 2 + 3) / 4 * 4;
}

template <int H>
__global__ void filterKernelX4(FilterLaunch p) {
  constexpr int K = 2 * H + 1;
  constexpr int W4 = (kX4Outputs + K - 1 + 3) / 4;  // float4s a window
  constexpr int TW = x4TileWidth<H>(), TH = kX4TileY + 2 * H;
  extern __shared__ float4 tile4[];
  float* tile = reinterpret_cast<float*>(tile4);
  const std::size_t np = static_cast<std::size_t>(p.width) * p.height;
  const std::size_t base = static_cast<std::size_t>(p.f0 + static_cast<int>(blockIdx.z)) * np;
  loadFilterTile(p, tile, blockIdx.x * kX4TileX - H, blockIdx.y * kX4TileY - H, TW, TH);
  const int xo = blockIdx.x * kX4TileX + threadIdx.x * kX4Outputs, y = blockIdx.y * kX4TileY + threadIdx.y;
  if (xo >= p.width || y >= p.height) return;
  float acc[kX4Outputs] = {};
#pragma unroll 1
  for (int dy = 0; dy < K; ++dy) {
    const float4* row =
        reinterpret_cast<const float4*>(tile + (threadIdx.y + dy) * TW + threadIdx.x * kX4Outputs);
    float v[4 * W4];
#pragma unroll
    for (int m = 0; m < W4; ++m) {
      const float4 f = row[m];
      v[4 * m] = f.x;
      v[4 * m + 1] = f.y;
      v[4 * m + 2] = f.z;
      v[4 * m + 3] = f.w;
    }
    const float* krow = c_filter + dy * K;
#pragma unroll
    for (int dx = 0; dx < K; ++dx) {
      const float k = krow[dx];
#pragma unroll
      for (int q = 0; q < kX4Outputs; ++q)
        acc[q] = fmaf(k, v[dx + q], acc[q]);
    }
  }
#pragma unroll
  for (int q = 0; q < kX4Outputs; ++q) {
    const int x = xo + q;
    if (x >= p.width) break;
    const std::size_t i = static_cast<std::size_t>(y) * p.width + x;
    p.out[base + i] = p.outScale ? __fmul_rn(acc[q], p.outScale[i]) : acc[q];
  }
}

template <int H>
void launchFilterX4(const FilterLaunch& q, cudaStream_t s) {
  const std::size_t shared = sizeof(float) * x4TileWidth<H>() * (kX4TileY + 2 * H);
  static bool configured = false;
  if (!configured) {
    ST_CUDA_CHECK(
        cudaFuncSetAttribute(filterKernelX4<H>, cudaFuncAttributeMaxDynamicSharedMemorySize, 96 * 1024));
    configured = true;
  }
  const dim3 grid((q.width + kX4TileX - 1) / kX4TileX, (q.height + kX4TileY - 1) / kX4TileY, q.f1 - q.f0);
  filterKernelX4<H><<<grid, dim3(32, kX4TileY), shared, s>>>(q);
  checkLaunch("filterKernelX4");
}

// The register-blocked filter for kernel half sizes 1-12 (false: another size, filterKernel's).
bool launchFilterX4Any(const FilterLaunch& q, cudaStream_t s) {
  switch (q.half) {
    case 1:
      launchFilterX4<1>(q, s);
      return true;
    case 2:
      launchFilterX4<2>(q, s);
      return true;
    case 3:
      launchFilterX4<3>(q, s);
      return true;
    case 4:
      launchFilterX4<4>(q, s);
      return true;
    case 5:
      launchFilterX4<5>(q, s);
      return true;
    case 6:
      launchFilterX4<6>(q, s);
      return true;
    case 7:
      launchFilterX4<7>(q, s);
      return true;
    case 8:
      launchFilterX4<8>(q, s);
      return true;
    case 9:
      launchFilterX4<9>(q, s);
      return true;
    case 10:
      launchFilterX4<10>(q, s);
      return true;
    case 11:
      launchFilterX4<11>(q, s);
      return true;
    case 12:
      launchFilterX4<12>(q, s);
      return true;
    default:
      return false;
  }
}

/// ST_GPU_FILTER_PLAIN=1: filterKernel, one output a thread, as before 2026-12-03 (read at each launch).
bool plainFilter() {
  const char* e = std::getenv("ST_GPU_FILTER_PLAIN");
  return e && *e && *e != '0';
}

__global__ void omegaKernel(const float* pix, const std::uint8_t* mask, const double* invS2,
                            const float* invVar, const std::uint32_t* covering, float* omega, int width,
                            int height, int nf) {
  const std::size_t np = static_cast<std::size_t>(width) * height;
  const std::size_t i = blockIdx.x * static_cast<std::size_t>(blockDim.x) + threadIdx.x;
  if (i >= np) return;
  double acc = 0.0;
  for (int n = 0; n < nf; ++n) {
    const std::size_t off = static_cast<std::size_t>(n) * np + i;
    const float f = pix[off];
    if (f != 0.0f && isfinite(f) && !(mask && mask[off])) acc = __dadd_rn(acc, invS2[n]);
  }
  const double frames =
      covering ? static_cast<double>(covering[i] > 1u ? covering[i] : 1u) : static_cast<double>(nf);
  omega[i] = static_cast<float>(__dmul_rn(acc / frames, static_cast<double>(invVar[i])));
}

__global__ void noiseSamplesKernel(const float* in, const std::uint8_t* mask, const float* filtered,
                                   int width, int height, int n, int half, float* out, int nx, int ny) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x, j = blockIdx.y * blockDim.y + threadIdx.y;
  if (i >= nx || j >= ny) return;
  const int x = half + 3 * i, y = half + 3 * j;
  const std::size_t np = static_cast<std::size_t>(width) * height;
  const std::size_t base = static_cast<std::size_t>(n) * np;
  bool bad = false;
  for (int yy = y - half; yy <= y + half && !bad; ++yy)
    for (int xx = x - half; xx <= x + half; ++xx) {
      if (xx < 0 || yy < 0 || xx >= width || yy >= height) {
        bad = true;
        break;
      }
      const std::size_t q = base + static_cast<std::size_t>(yy) * width + xx;
      const float v = in[q];
      if (v == 0.0f || !isfinite(v) || (mask && mask[q])) {
        bad = true;
        break;
      }
    }
  out[static_cast<std::size_t>(j) * nx + i] =
      bad ? __int_as_float(0x7fc00000) : filtered[base + static_cast<std::size_t>(y) * width + x];
}

unsigned blocksFor(std::size_t n, unsigned threads) {
  return static_cast<unsigned>((n + threads - 1) / threads);
}

}  // namespace

void launchBackgroundPrepare(const BackgroundLaunch& p, cudaStream_t s) {
  const std::size_t np = static_cast<std::size_t>(p.width) * p.height;
  for (int k0 = 0; k0 < p.nk; k0 += 65535) {
    BackgroundLaunch q = p;
    const int count = p.nk - k0 < 65535 ? p.nk - k0 : 65535;
    q.usedFrames = p.usedFrames + k0;
    q.buf = p.buf + static_cast<std::size_t>(k0) * np;
    q.nk = count;
    backgroundPrepareKernel<<<dim3(blocksFor(np, 256), count), 256, 0, s>>>(q);
    checkLaunch("backgroundPrepareKernel");
  }
}

void launchBackgroundStrongCut(const BackgroundLaunch& p, cudaStream_t s) {
  const std::size_t np = static_cast<std::size_t>(p.width) * p.height;
  backgroundStrongCutKernel<<<blocksFor(np, 128), 128, 0, s>>>(p);
  checkLaunch("backgroundStrongCutKernel");
}

void launchBackgroundClip(const BackgroundLaunch& p, cudaStream_t s) {
  const std::size_t np = static_cast<std::size_t>(p.width) * p.height;
  backgroundClipKernel<<<blocksFor(np, 128), 128, 0, s>>>(p);
  checkLaunch("backgroundClipKernel");
}

void launchBackgroundSubtract(const BackgroundLaunch& p, cudaStream_t s) {
  const std::size_t np = static_cast<std::size_t>(p.width) * p.height;
  backgroundSubtractKernel<<<blocksFor(np, 128), 128, 0, s>>>(p);
  checkLaunch("backgroundSubtractKernel");
}

void setFilterKernel(const float* kernel, int half, cudaStream_t s) {
  const int k = 2 * half + 1;
  ST_CUDA_CHECK(
      cudaMemcpyToSymbolAsync(c_filter, kernel, sizeof(float) * k * k, 0, cudaMemcpyHostToDevice, s));
}

bool filterRegisterBlocked(int half) {
  return half >= 1 && half <= 12 && !plainFilter();
}

void launchFilter(const FilterLaunch& p, cudaStream_t s) {
  const std::size_t shared = sizeof(float) * (kTileX + 2 * p.half) * (kTileY + 2 * p.half);
  static bool configured = false;
  if (!configured) {
    ST_CUDA_CHECK(cudaFuncSetAttribute(filterKernel, cudaFuncAttributeMaxDynamicSharedMemorySize, 96 * 1024));
    configured = true;
  }
  const bool plain = plainFilter();
  for (int f0 = p.f0; f0 < p.f1; f0 += 65535) {
    FilterLaunch q = p;
    q.f0 = f0;
    q.f1 = p.f1 - f0 < 65535 ? p.f1 : f0 + 65535;
    if (!plain && launchFilterX4Any(q, s)) continue;
    const dim3 grid((p.width + kTileX - 1) / kTileX, (p.height + kTileY - 1) / kTileY, q.f1 - q.f0);
    filterKernel<<<grid, dim3(kTileX, kTileY), shared, s>>>(q);
    checkLaunch("filterKernel");
  }
}

void launchOmega(const float* pix, const std::uint8_t* mask, const double* invS2, const float* invVar,
                 const std::uint32_t* covering, float* omega, int width, int height, int nf, cudaStream_t s) {
  const std::size_t np = static_cast<std::size_t>(width) * height;
  omegaKernel<<<blocksFor(np, 256), 256, 0, s>>>(pix, mask, invS2, invVar, covering, omega, width, height,
                                                 nf);
  checkLaunch("omegaKernel");
}

void launchNoiseSamples(const float* in, const std::uint8_t* mask, const float* filtered, int width,
                        int height, int n, int half, float* out, int nx, int ny, cudaStream_t s) {
  const dim3 block(32, 8);
  const dim3 grid(blocksFor(nx, 32), blocksFor(ny, 8));
  noiseSamplesKernel<<<grid, block, 0, s>>>(in, mask, filtered, width, height, n, half, out, nx, ny);
  checkLaunch("noiseSamplesKernel");
}

}  // namespace st::gpu

// detect::stackAtSkyRate on the device (sky_stack_kernels.hpp). Canvas pixel (i, j) takes frame n's pixel
// (i + x0 + shiftX[n], j + y0 + shiftY[n]) when it lies in the frame and is not masked: the sum of
// (double(v) - subtract) in frame order, the count, the largest value; mean = float(sum / count), and 0 mean
// and maximum where no frame contributed (core/detect/sky_stack.cpp).
#include <algorithm>
#include <cmath>

#include "cuda_check.hpp"
#include "sky_stack_kernels.hpp"

namespace st::gpu {
namespace {

__global__ void skyStackKernel(SkyStackLaunch p) {
  const int i = static_cast<int>(blockIdx.x * blockDim.x + threadIdx.x);
  const int j = static_cast<int>(blockIdx.y);
  if (i >= p.cw || j >= p.ch) return;
  const std::size_t np = static_cast<std::size_t>(p.width) * p.height;
  double sum = 0.0;
  float cnt = 0.0f;
  float mx = -INFINITY;
  for (int n = p.first; n < p.last; ++n) {
    const int y = p.y0 + j + __ldg(p.shiftY + n);
    const int x = i + p.x0 + __ldg(p.shiftX + n);
    if (y < 0 || y >= p.height || x < 0 || x >= p.width) continue;
    const std::size_t q = static_cast<std::size_t>(n) * np + static_cast<std::size_t>(y) * p.width + x;
    if (p.mask && p.mask[q]) continue;
    const float v = p.pix[q];
    sum = __dadd_rn(sum, __dsub_rn(static_cast<double>(v), p.subtract));
    cnt += 1.0f;
    mx = mx < v ? v : mx;  // std::max(mx, v)
  }
  const std::size_t o = static_cast<std::size_t>(j) * p.cw + i;
  p.mean[o] = cnt > 0.0f ? static_cast<float>(__ddiv_rn(sum, static_cast<double>(cnt))) : 0.0f;
  p.count[o] = cnt;
  p.max[o] = cnt == 0.0f ? 0.0f : mx;
}

__global__ void shiftedSumsKernel(ShiftedSumsLaunch p) {
  const int x = static_cast<int>(blockIdx.x * blockDim.x + threadIdx.x);
  const int y = static_cast<int>(blockIdx.y);
  const int b = static_cast<int>(blockIdx.z);
  if (x >= p.width || y >= p.height || b >= p.blocks) return;
  const std::size_t np = static_cast<std::size_t>(p.width) * p.height;
  double sum = 0.0, cnt = 0.0;
  const int e0 = p.start[b], e1 = p.start[b + 1];
  for (int e = e0; e < e1; ++e) {
    const int n = p.first[b] + (e - e0);
    const int xs = x + __ldg(p.sx + e), ys = y + __ldg(p.sy + e);
    if (xs < 0 || xs >= p.width || ys < 0 || ys >= p.height) continue;
    const std::size_t q = static_cast<std::size_t>(n) * np + static_cast<std::size_t>(ys) * p.width + xs;
    if (p.mask && p.mask[q]) continue;
    sum = __dadd_rn(sum, __dsub_rn(static_cast<double>(p.pix[q]), p.background));
    cnt = __dadd_rn(cnt, 1.0);
  }
  const std::size_t o = static_cast<std::size_t>(b) * np + static_cast<std::size_t>(y) * p.width + x;
  if (p.doubleMean) {
    p.doubleMean[o] = cnt > 0.0 ? __ddiv_rn(sum, cnt) : 0.0;
    return;
  }
  if (p.mean) {
    p.mean[o] = cnt > 0.0 ? static_cast<float>(__ddiv_rn(sum, cnt)) : 0.0f;
    p.frames[o] = static_cast<float>(cnt);
    return;
  }
  p.sum[o] = sum;
  p.count[o] = cnt;
}

// detect::detail::filteredSnr (core/detect/star_footprint.cpp): the taps inside the image, rows then columns
// ascending, each product rounded before its sum (no fused multiply-add), so the CPU's values bit for bit.
__global__ void filteredSnrKernel(const float* rc, const float* cnt, const double* k, int w, int h, int r,
                                  double sigma, float* out) {
  const int x = static_cast<int>(blockIdx.x * blockDim.x + threadIdx.x);
  const int y = static_cast<int>(blockIdx.y);
  if (x >= w || y >= h) return;
  const int kw = 2 * r + 1;
  const int j0 = max(-r, -y), j1 = min(r, h - 1 - y), i0 = max(-r, -x), i1 = min(r, w - 1 - x);
  double num = 0.0, den = 0.0;
  for (int j = j0; j <= j1; ++j) {
    const std::size_t row = static_cast<std::size_t>(y + j) * w + x;
    const double* kr = k + static_cast<std::size_t>(j + r) * kw + r;
    for (int i = i0; i <= i1; ++i) {
      const double kv = __ldg(kr + i);
      num = __dadd_rn(num, __dmul_rn(kv, static_cast<double>(__ldg(rc + row + i))));
      den = __dadd_rn(den, __dmul_rn(__dmul_rn(kv, kv), static_cast<double>(__ldg(cnt + row + i))));
    }
  }
  out[static_cast<std::size_t>(y) * w + x] =
      den > 0.0 ? __double2float_rn(__ddiv_rn(num, __dmul_rn(sigma, __dsqrt_rn(den)))) : 0.0f;
}

// calib::cosmicRayPreTestWords: frame n's reference frames are its neighbours (1 and 2 for the first, the
// two before it for the last); !(f - max(fa, fb) <= thr) with max as std::max (fa unless fa < fb) and the
// subtraction rounded as on the CPU. Lane 0 of each warp appends its warp's word when non-zero (blockDim
// is a multiple of 32, so a warp's first flat index is a multiple of 32).
__global__ void cosmicRayPreTestKernel(const float* pix, std::size_t nf, std::size_t np, float thr,
                                       unsigned long long* out, unsigned long long capacity,
                                       unsigned long long* count) {
  const std::size_t total = nf * np;
  const std::size_t k = blockIdx.x * static_cast<std::size_t>(blockDim.x) + threadIdx.x;
  bool pass = false;
  if (k < total) {
    const std::size_t n = k / np, i = k - n * np;
    const std::size_t a = n == 0 ? 1 : (n + 1 == nf ? nf - 2 : n - 1);
    const std::size_t b = n == 0 ? 2 : (n + 1 == nf ? nf - 3 : n + 1);
    const float fa = __ldg(pix + a * np + i), fb = __ldg(pix + b * np + i);
    const float mx = fa < fb ? fb : fa;
    pass = !(__fsub_rn(__ldg(pix + k), mx) <= thr);
  }
  const unsigned word = __ballot_sync(0xffffffffu, pass);
  if ((threadIdx.x & 31u) == 0 && word != 0) {
    const unsigned long long slot = atomicAdd(count, 1ull);
    if (slot < capacity) out[slot] = (static_cast<unsigned long long>(k / 32) << 32) | word;
  }
}

template <class T>
__global__ void scatterKernel(T* pix, const std::uint64_t* index, const T* value, std::size_t n) {
  const std::size_t k = blockIdx.x * static_cast<std::size_t>(blockDim.x) + threadIdx.x;
  if (k < n) pix[index[k]] = value[k];
}

template <class T>
void scatter(T* pix, const std::uint64_t* index, const T* value, std::size_t n, cudaStream_t s) {
  if (n == 0) return;
  constexpr int kThreads = 256;
  scatterKernel<T>
      <<<static_cast<unsigned>((n + kThreads - 1) / kThreads), kThreads, 0, s>>>(pix, index, value, n);
  checkLaunch("scatterKernel");
}

}  // namespace

void launchShiftedSums(const ShiftedSumsLaunch& p, cudaStream_t s) {
  if (p.width <= 0 || p.height <= 0 || p.blocks <= 0) return;
  constexpr int kThreads = 128;
  const dim3 grid(static_cast<unsigned>((p.width + kThreads - 1) / kThreads), static_cast<unsigned>(p.height),
                  static_cast<unsigned>(p.blocks));
  shiftedSumsKernel<<<grid, kThreads, 0, s>>>(p);
  checkLaunch("shiftedSumsKernel");
}

void launchScatter(float* pix, const std::uint64_t* index, const float* value, std::size_t n,
                   cudaStream_t s) {
  scatter(pix, index, value, n, s);
}

void launchScatter(std::uint8_t* mask, const std::uint64_t* index, const std::uint8_t* value, std::size_t n,
                   cudaStream_t s) {
  scatter(mask, index, value, n, s);
}

namespace {

__global__ void maskInAllFramesKernel(std::uint8_t* mask, const std::uint64_t* pixels, std::size_t count,
                                      std::size_t nf, std::size_t np) {
  const std::size_t j = blockIdx.x * static_cast<std::size_t>(blockDim.x) + threadIdx.x;
  if (j >= count) return;
  const std::size_t i = pixels[j];
  for (std::size_t n = blockIdx.y; n < nf; n += gridDim.y)
    mask[n * np + i] = 1;
}

}  // namespace

void launchMaskInAllFrames(std::uint8_t* mask, const std::uint64_t* pixels, std::size_t count, std::size_t nf,
                           std::size_t np, cudaStream_t s) {
  if (count == 0 || nf == 0) return;
  constexpr int kThreads = 128;
  const dim3 grid(static_cast<unsigned>((count + kThreads - 1) / kThreads),
                  static_cast<unsigned>(std::min<std::size_t>(nf, 1024)));
  maskInAllFramesKernel<<<grid, kThreads, 0, s>>>(mask, pixels, count, nf, np);
  checkLaunch("maskInAllFramesKernel");
}

void launchCosmicRayPreTest(const float* pix, std::size_t nf, std::size_t np, float thr,
                            unsigned long long* out, unsigned long long capacity, unsigned long long* count,
                            cudaStream_t s) {
  const std::size_t total = nf * np;
  if (total == 0 || nf < 3) return;
  constexpr int kThreads = 256;
  cosmicRayPreTestKernel<<<static_cast<unsigned>((total + kThreads - 1) / kThreads), kThreads, 0, s>>>(
      pix, nf, np, thr, out, capacity, count);
  checkLaunch("cosmicRayPreTestKernel");
}

void launchFilteredSnr(const float* rc, const float* count, const double* k, int width, int height, int r,
                       double sigma, float* out, cudaStream_t s) {
  if (width <= 0 || height <= 0) return;
  constexpr int kThreads = 128;
  const dim3 grid(static_cast<unsigned>((width + kThreads - 1) / kThreads), static_cast<unsigned>(height));
  filteredSnrKernel<<<grid, kThreads, 0, s>>>(rc, count, k, width, height, r, sigma, out);
  checkLaunch("filteredSnrKernel");
}

void launchSkyStack(const SkyStackLaunch& p, cudaStream_t s) {
  if (p.cw <= 0 || p.ch <= 0) return;
  constexpr int kThreads = 128;
  const dim3 grid(static_cast<unsigned>((p.cw + kThreads - 1) / kThreads), static_cast<unsigned>(p.ch));
  skyStackKernel<<<grid, kThreads, 0, s>>>(p);
  checkLaunch("skyStackKernel");
}

}  // namespace st::gpu

// detect::stackAtSkyRate on the device (sky_stack_kernels.hpp). Canvas pixel (i, j) takes frame n's pixel
// (i + x0 + shiftX[n], j + y0 + shiftY[n]) when it lies in the frame and is not masked: the sum of
// (double(v) - subtract) in frame order, the count, the largest value; mean = float(sum / count), and 0 mean
// and maximum where no frame contributed (core/detect/sky_stack.cpp).
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
  p.sum[o] = sum;
  p.count[o] = cnt;
}

__global__ void scatterKernel(float* pix, const std::uint64_t* index, const float* value, std::size_t n) {
  const std::size_t k = blockIdx.x * static_cast<std::size_t>(blockDim.x) + threadIdx.x;
  if (k < n) pix[index[k]] = value[k];
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
  if (n == 0) return;
  constexpr int kThreads = 256;
  scatterKernel<<<static_cast<unsigned>((n + kThreads - 1) / kThreads), kThreads, 0, s>>>(pix, index, value,
                                                                                          n);
  checkLaunch("scatterKernel");
}

void launchSkyStack(const SkyStackLaunch& p, cudaStream_t s) {
  if (p.cw <= 0 || p.ch <= 0) return;
  constexpr int kThreads = 128;
  const dim3 grid(static_cast<unsigned>((p.cw + kThreads - 1) / kThreads), static_cast<unsigned>(p.ch));
  skyStackKernel<<<grid, kThreads, 0, s>>>(p);
  checkLaunch("skyStackKernel");
}

}  // namespace st::gpu

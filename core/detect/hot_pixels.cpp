#include "st/detect/hot_pixels.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "st/common/parallel.hpp"
#include "st/common/prefault.hpp"

namespace st::detect {

std::vector<std::size_t> findHotPixels(const FrameCube& cube, double background, double sigma,
                                       const HotPixelParams& params, CancelToken& cancel) {
  const std::size_t nf = cube.frameCount(), np = cube.framePixels();
  const int blocks =
      static_cast<int>(std::clamp<std::size_t>(params.blocks, 1, std::max<std::size_t>(1, nf)));
  std::vector<float> minExcess(np, 1e30f);
  const auto& mask = cube.mask();
  for (int b = 0; b < blocks; ++b) {
    const std::size_t n0 = nf * b / blocks, n1 = nf * (b + 1) / blocks;
    // Frame by frame over a chunk of pixels (contiguous reads; pixel by pixel across the frames touched a
    // page per sample): the same sums in the same order.
    parallelFor(np, 16384, [&](std::size_t i0, std::size_t i1) {
      cancel.throwIfCancelled();
      std::vector<double> s(i1 - i0, 0.0);
      std::vector<std::uint32_t> c(i1 - i0, 0);
      for (std::size_t n = n0; n < n1; ++n) {
        const float* f = cube.frame(n);
        const std::uint8_t* m = mask.empty() ? nullptr : mask.data() + n * np;
        for (std::size_t i = i0; i < i1; ++i) {
          const bool in = !m || !m[i];
          s[i - i0] += in ? static_cast<double>(f[i]) : 0.0;
          c[i - i0] += in;
        }
      }
      for (std::size_t i = i0; i < i1; ++i) {
        const float e = c[i - i0] ? static_cast<float>(s[i - i0] / c[i - i0] - background) : 0.0f;
        minExcess[i] = std::min(minExcess[i], e);
      }
    });
  }
  return hotPixelsFromExcess(minExcess, cube.width(), cube.height(), nf, sigma, params);
}

std::vector<std::size_t> hotPixelsFromExcess(const std::vector<float>& minExcess, int w, int h,
                                             std::size_t nf, double sigma, const HotPixelParams& params) {
  const int blocks =
      static_cast<int>(std::clamp<std::size_t>(params.blocks, 1, std::max<std::size_t>(1, nf)));
  const double blockSigma = sigma / std::sqrt(std::max<double>(1.0, static_cast<double>(nf) / blocks));
  std::vector<std::size_t> hot;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * w + x;
      const float e = minExcess[i];
      if (!(e > params.snr * blockSigma)) continue;
      float neighbour = 0.0f;
      if (x > 0) neighbour = std::max(neighbour, minExcess[i - 1]);
      if (x + 1 < w) neighbour = std::max(neighbour, minExcess[i + 1]);
      if (y > 0) neighbour = std::max(neighbour, minExcess[i - w]);
      if (y + 1 < h) neighbour = std::max(neighbour, minExcess[i + w]);
      if (e > params.sharpness * neighbour) hot.push_back(i);
    }
  return hot;
}

std::size_t maskPixelsInAllFrames(FrameCube& cube, const std::vector<std::size_t>& pixels) {
  if (pixels.empty()) return 0;
  auto& mask = cube.mask();
  // 393 MB for 1500 x 512^2, a few pixels set in each frame: the kernel's zero pages except where written.
  if (mask.empty()) mask = sparseZeros(cube.pixels().size());
  const std::size_t np = cube.framePixels();
  // Frames on every core: each write to a page that is still the kernel's zero page faults it in (~20 hot
  // pixels in each of 1500 frames: up to 30,000 faults; on one thread the stage took 60-76 ms on an H200
  // host's 16-thread Xeon, 2026-12-01, where it took ~20 ms with the mask written whole on every core).
  parallelFor(cube.frameCount(), 8, [&](std::size_t n0, std::size_t n1) {
    for (std::size_t n = n0; n < n1; ++n)
      for (std::size_t i : pixels)
        mask[n * np + i] = 1;
  });
  return pixels.size();
}

}  // namespace st::detect

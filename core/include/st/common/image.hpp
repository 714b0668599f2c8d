#pragma once
// A single 2-D float image, row-major: pixel (x, y) is at index y * width + x, x = column = FITS axis 1,
// 0-based, pixel centres at integers (ARCHITECTURE.md, "Conventions").
#include <cstddef>
#include <vector>

namespace st {

struct Image {
  int width = 0;
  int height = 0;
  std::vector<float> pixels;

  Image() = default;
  Image(int w, int h, float fill = 0.0f)
      : width(w), height(h), pixels(static_cast<std::size_t>(w) * static_cast<std::size_t>(h), fill) {}

  [[nodiscard]] std::size_t size() const noexcept { return pixels.size(); }
  [[nodiscard]] bool empty() const noexcept { return pixels.empty(); }
  [[nodiscard]] bool contains(int x, int y) const noexcept {
    return x >= 0 && y >= 0 && x < width && y < height;
  }
  float& at(int x, int y) { return pixels[static_cast<std::size_t>(y) * width + x]; }
  [[nodiscard]] float at(int x, int y) const { return pixels[static_cast<std::size_t>(y) * width + x]; }
  float* data() noexcept { return pixels.data(); }
  [[nodiscard]] const float* data() const noexcept { return pixels.data(); }
};

}  // namespace st

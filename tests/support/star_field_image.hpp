#pragma once
// Test images like the sky rate's links' (thresholded and compressed star fields), for the phase
// correlation's tests on the CPU (tests/core) and the device (tests/gpu). Needs OpenCV's include path.
#include <algorithm>
#include <cmath>
#include <random>

#include <opencv2/core.hpp>

namespace st::test {

// A compressed star image as the sky rate makes (log1p(v / t) above the threshold t, else 0): `n` Gaussian
// stars of sigma 1.3 px at random places moved by (dx, dy), with noise.
inline cv::Mat starField(int w, int h, int n, double dx, double dy, unsigned seed) {
  std::mt19937 pos(seed), noise(seed * 7 + static_cast<unsigned>(1000 * dx + 10 * dy));
  std::uniform_real_distribution<double> ux(0.0, w), uy(0.0, h), uf(5.0, 200.0);
  std::normal_distribution<double> gn(0.0, 1.0);
  cv::Mat v = cv::Mat::zeros(h, w, CV_64F);
  for (int k = 0; k < n; ++k) {
    const double cx = ux(pos) + dx, cy = uy(pos) + dy, f = uf(pos);
    for (int y = std::max(0, static_cast<int>(cy) - 6); y < std::min(h, static_cast<int>(cy) + 7); ++y)
      for (int x = std::max(0, static_cast<int>(cx) - 6); x < std::min(w, static_cast<int>(cx) + 7); ++x)
        v.at<double>(y, x) += f * std::exp(-((x - cx) * (x - cx) + (y - cy) * (y - cy)) / (2 * 1.3 * 1.3));
  }
  cv::Mat out = cv::Mat::zeros(h, w, CV_64F);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const double s = v.at<double>(y, x) + gn(noise);
      out.at<double>(y, x) = s > 3.0 ? std::log1p(s / 3.0) : 0.0;
    }
  return out;
}

}  // namespace st::test

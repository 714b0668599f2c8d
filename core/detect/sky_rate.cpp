#include "st/detect/sky_rate.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

namespace st::detect {
namespace {

struct Block {
  cv::Mat image;  // CV_64F
  double tS = 0.0;
};

Block blockMean(const FrameCube& cube, std::size_t first, std::size_t last, double background, double sigma,
                double detectSigma, const std::vector<double>& dt) {
  const int w = cube.width(), h = cube.height();
  Block b;
  b.image = cv::Mat::zeros(h, w, CV_64F);
  std::vector<float> cnt(cube.framePixels(), 0.0f);
  const auto& mask = cube.mask();
  for (std::size_t n = first; n < last; ++n) {
    const float* f = cube.frame(n);
    for (int y = 0; y < h; ++y) {
      double* row = b.image.ptr<double>(y);
      for (int x = 0; x < w; ++x) {
        const std::size_t i = static_cast<std::size_t>(y) * w + x;
        if (!mask.empty() && mask[n * cube.framePixels() + i]) continue;
        row[x] += f[i] - background;
        cnt[i] += 1.0f;
      }
    }
    b.tS += dt[n];
  }
  b.tS /= static_cast<double>(last - first);
  const double thr = detectSigma * sigma / std::sqrt(static_cast<double>(last - first));
  for (int y = 0; y < h; ++y) {
    double* row = b.image.ptr<double>(y);
    for (int x = 0; x < w; ++x) {
      const float c = cnt[static_cast<std::size_t>(y) * w + x];
      const double v = c > 0 ? row[x] / c : 0.0;
      // Bright sources only, compressed so that one saturated star does not decide alone.
      row[x] = v > thr ? std::log1p(v / thr) : 0.0;
    }
  }
  return b;
}

}  // namespace

SkyRate measureSkyRate(const FrameCube& cube, double background, double sigma, const SkyRateParams& params,
                       CancelToken& cancel) {
  SkyRate out;
  const std::size_t nf = cube.frameCount();
  const int nb = static_cast<int>(std::min<std::size_t>(std::max(2, params.blocks), nf));
  if (nb < 2 || cube.timeSpanS() <= 0.0) {
    out.note = "sky rate: fewer than two frames or no time span, assumed 0";
    return out;
  }
  const auto dt = cube.timeOffsetsS();
  std::vector<Block> blocks;
  for (int k = 0; k < nb; ++k) {
    cancel.throwIfCancelled();
    blocks.push_back(blockMean(cube, nf * k / nb, nf * (k + 1) / nb, background, sigma, params.detectSigma, dt));
  }
  cv::Mat window;
  cv::createHanningWindow(window, blocks.front().image.size(), CV_64F);
  std::vector<double> vx, vy;
  double minResponse = 1.0;
  for (int k = 0; k + 1 < nb; ++k) {
    double response = 0.0;
    const cv::Point2d d = cv::phaseCorrelate(blocks[k].image, blocks[k + 1].image, window, &response);
    minResponse = std::min(minResponse, response);
    const double span = blocks[k + 1].tS - blocks[k].tS;
    if (span <= 0) continue;
    vx.push_back(d.x / span);
    vy.push_back(d.y / span);
  }
  if (vx.empty() || minResponse < params.minResponse) {
    out.note = "sky rate: no reliable star pattern (phase-correlation peak " + std::to_string(minResponse) +
               "), assumed 0";
    out.response = minResponse;
    return out;
  }
  auto median = [](std::vector<double> v) {
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  };
  out.rate = {median(vx), median(vy)};
  out.response = minResponse;
  out.reliable = true;
  out.note = "sky rate: measured from adjacent blocks of frames";
  const double span = blocks.back().tS - blocks.front().tS;
  if (std::abs(out.rate.vx * span) < 0.5 * cube.width() && std::abs(out.rate.vy * span) < 0.5 * cube.height()) {
    double response = 0.0;
    const cv::Point2d d = cv::phaseCorrelate(blocks.front().image, blocks.back().image, window, &response);
    const Velocity refined{d.x / span, d.y / span};
    // Accept the long baseline when it agrees with the short ones to within a pixel over one block step.
    const double step = blocks[1].tS - blocks[0].tS;
    if (response >= params.minResponse && std::abs(refined.vx - out.rate.vx) * step < 1.0 &&
        std::abs(refined.vy - out.rate.vy) * step < 1.0) {
      out.rate = refined;
      out.response = response;
      out.note = "sky rate: measured from the first and last blocks of frames";
    }
  }
  return out;
}

}  // namespace st::detect

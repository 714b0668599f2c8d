#include "st/detect/sky_rate.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "st/detect/sky_stack.hpp"

namespace st::detect {
namespace {

struct Block {
  cv::Mat image;  // CV_64F
  double tS = 0.0;
};

// Mean of frames [first, last) minus the background; unmasked samples only.
cv::Mat meanOf(const FrameCube& cube, std::size_t first, std::size_t last, double background) {
  const int w = cube.width(), h = cube.height();
  cv::Mat image = cv::Mat::zeros(h, w, CV_64F);
  std::vector<float> cnt(cube.framePixels(), 0.0f);
  const auto& mask = cube.mask();
  for (std::size_t n = first; n < last; ++n) {
    const float* f = cube.frame(n);
    for (int y = 0; y < h; ++y) {
      double* row = image.ptr<double>(y);
      for (int x = 0; x < w; ++x) {
        const std::size_t i = static_cast<std::size_t>(y) * w + x;
        if (!mask.empty() && mask[n * cube.framePixels() + i]) continue;
        row[x] += f[i] - background;
        cnt[i] += 1.0f;
      }
    }
  }
  for (int y = 0; y < h; ++y) {
    double* row = image.ptr<double>(y);
    for (int x = 0; x < w; ++x) {
      const float c = cnt[static_cast<std::size_t>(y) * w + x];
      row[x] = c > 0 ? row[x] / c : 0.0;
    }
  }
  return image;
}

// A block's image: the smaller of the means of its two halves, so that a cosmic ray (in one frame, one half)
// does not survive while a star (in both) does; then faint pixels zeroed and the rest compressed.
Block blockMean(const FrameCube& cube, std::size_t first, std::size_t last, double background, double sigma,
                double detectSigma, const std::vector<double>& dt) {
  const int w = cube.width(), h = cube.height();
  Block b;
  const std::size_t mid = first + std::max<std::size_t>(1, (last - first) / 2);
  b.image = mid < last ? cv::min(meanOf(cube, first, mid, background), meanOf(cube, mid, last, background))
                       : meanOf(cube, first, last, background);
  for (std::size_t n = first; n < last; ++n)
    b.tS += dt[n];
  b.tS /= static_cast<double>(last - first);
  const double thr =
      detectSigma * sigma / std::sqrt(std::max<double>(1.0, static_cast<double>(last - first) / 2));
  for (int y = 0; y < h; ++y) {
    double* row = b.image.ptr<double>(y);
    for (int x = 0; x < w; ++x) {
      const double v = row[x];
      // Bright sources only, compressed so that one saturated star does not decide alone.
      row[x] = v > thr ? std::log1p(v / thr) : 0.0;
    }
  }
  return b;
}

// Image of a sky-rate stack for phase correlation: bright pixels only, compressed; 0 where no frame.
cv::Mat stackImage(const SkyStack& s, double thr) {
  cv::Mat m = cv::Mat::zeros(s.mean.height, s.mean.width, CV_64F);
  for (int y = 0; y < s.mean.height; ++y) {
    double* row = m.ptr<double>(y);
    for (int x = 0; x < s.mean.width; ++x) {
      const double c = s.count.at(x, y), v = s.mean.at(x, y);
      const double t = thr / std::sqrt(std::max(1.0, c));
      row[x] = c > 0 && v > t ? std::log1p(v / t) : 0.0;
    }
  }
  return m;
}

// Median offset of bright, unsaturated-looking stars between two stacks on the same canvas: local maxima of
// `a` above `thr` (counts per frame), flux-weighted centroids in a (2r+1)^2 box in both. False when < 3.
bool centroidOffset(const SkyStack& a, const SkyStack& b, double thr, int r, cv::Point2d* d) {
  const int w = a.mean.width, h = a.mean.height;
  std::vector<double> dx, dy;
  auto centroid = [&](const SkyStack& s, int cx, int cy, double* ox, double* oy) {
    double sw = 0, sx = 0, sy = 0;
    for (int y = cy - r; y <= cy + r; ++y)
      for (int x = cx - r; x <= cx + r; ++x) {
        if (s.count.at(x, y) <= 0) return false;
        const double v = std::max(0.0f, s.mean.at(x, y));
        sw += v, sx += v * x, sy += v * y;
      }
    if (sw <= 0) return false;
    *ox = sx / sw, *oy = sy / sw;
    return true;
  };
  for (int y = r + 1; y < h - r - 1 && dx.size() < 200; ++y)
    for (int x = r + 1; x < w - r - 1; ++x) {
      const float v = a.mean.at(x, y);
      if (v < thr) continue;
      bool peak = true;
      for (int j = -1; j <= 1 && peak; ++j)
        for (int i = -1; i <= 1; ++i)
          if ((i || j) && a.mean.at(x + i, y + j) >= v) peak = false;
      if (!peak) continue;
      double ax, ay, bx, by;
      if (centroid(a, x, y, &ax, &ay) && centroid(b, x, y, &bx, &by))
        dx.push_back(bx - ax), dy.push_back(by - ay);
    }
  if (dx.size() < 3) return false;
  std::nth_element(dx.begin(), dx.begin() + dx.size() / 2, dx.end());
  std::nth_element(dy.begin(), dy.begin() + dy.size() / 2, dy.end());
  *d = {dx[dx.size() / 2], dy[dy.size() / 2]};
  return true;
}

// Refines a rate: stacks of the first and last thirds of the frames at `rate` put the stars at the same
// reference positions when the rate is right; their offset over the time between them is the residual.
Velocity refineRate(const FrameCube& cube, Velocity rate, double background, double sigma, double detectSigma,
                    double minResponse, double* response, CancelToken& cancel) {
  const std::size_t nf = cube.frameCount(), third = std::max<std::size_t>(1, nf / 3);
  const auto dt = cube.timeOffsetsS();
  NullProgress none;
  for (int it = 0; it < 4; ++it) {
    const SkyStack a = stackAtSkyRate(cube, rate, background, none, cancel, 0, third);
    const SkyStack b = stackAtSkyRate(cube, rate, background, none, cancel, nf - third, nf);
    double ta = 0.0, tb = 0.0;
    for (std::size_t n = 0; n < third; ++n)
      ta += dt[n] / third, tb += dt[nf - third + n] / third;
    if (tb <= ta) break;
    cv::Mat window;
    cv::createHanningWindow(window, cv::Size(a.mean.width, a.mean.height), CV_64F);
    double r = 0.0;
    cv::Point2d d = cv::phaseCorrelate(stackImage(a, detectSigma * sigma), stackImage(b, detectSigma * sigma),
                                       window, &r);
    if (r < minResponse) break;
    *response = r;
    // Once the stacks nearly coincide, star centroids measure the offset more precisely than the phase
    // correlation's sub-pixel peak.
    cv::Point2d c;
    const double thr = 20.0 * sigma / std::sqrt(static_cast<double>(third));
    if (std::hypot(d.x, d.y) < 1.5 && centroidOffset(a, b, thr, 3, &c)) d = c;
    rate.vx += d.x / (tb - ta);
    rate.vy += d.y / (tb - ta);
    if (std::hypot(d.x, d.y) < 0.02) break;
  }
  return rate;
}

}  // namespace

SkyRate measureSkyRate(const FrameCube& cube, double background, double sigma, const SkyRateParams& params,
                       CancelToken& cancel) {
  SkyRate out;
  const std::size_t nf = cube.frameCount();
  // Pairs of short adjacent blocks spread over the cube: short so that drifting stars do not streak much.
  const std::size_t len =
      std::clamp<std::size_t>(nf / 8, 1, static_cast<std::size_t>(std::max(1, params.blockFrames)));
  const int pairs = std::max(1, params.blocks);
  if (nf < 2 * len || nf < 2 || cube.timeSpanS() <= 0.0) {
    out.note = "sky rate: fewer than two frames or no time span, assumed 0";
    return out;
  }
  const auto dt = cube.timeOffsetsS();
  cv::Mat window;
  cv::createHanningWindow(window, cv::Size(cube.width(), cube.height()), CV_64F);
  std::vector<double> vx, vy, responses;
  for (int k = 0; k < pairs; ++k) {
    cancel.throwIfCancelled();
    const std::size_t start = pairs > 1 ? (nf - 2 * len) * static_cast<std::size_t>(k) / (pairs - 1) : 0;
    const Block a = blockMean(cube, start, start + len, background, sigma, params.detectSigma, dt);
    const Block b = blockMean(cube, start + len, start + 2 * len, background, sigma, params.detectSigma, dt);
    double response = 0.0;
    const cv::Point2d d = cv::phaseCorrelate(a.image, b.image, window, &response);
    const double span = b.tS - a.tS;
    if (span <= 0) continue;
    vx.push_back(d.x / span);
    vy.push_back(d.y / span);
    responses.push_back(response);
  }
  auto median = [](std::vector<double> v) {
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  };
  const double medianResponse = responses.empty() ? 0.0 : median(responses);
  out.response = medianResponse;
  if (vx.empty() || medianResponse < params.minResponse) {
    out.note = "sky rate: no reliable star pattern (phase-correlation peak " +
               std::to_string(medianResponse) + "), assumed 0";
    return out;
  }
  out.rate = {median(vx), median(vy)};
  out.reliable = true;
  const Velocity first = out.rate;
  double response = out.response;
  out.rate = refineRate(cube, out.rate, background, sigma, params.detectSigma, params.minResponse, &response,
                        cancel);
  out.response = response;
  out.note = "sky rate: pairs of short blocks gave (" + std::to_string(first.vx) + ", " +
             std::to_string(first.vy) + ") px/s, refined on stacks of the first and last thirds";
  return out;
}

}  // namespace st::detect

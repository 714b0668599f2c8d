#include "st/detect/sky_rate.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "st/detect/sky_stack.hpp"

namespace st::detect {
namespace {

// Sources voting in the consensus offsets peak at >= 4 times the detection threshold (log1p(4) in the
// compressed images): bright enough to centroid to a small fraction of a pixel.
const double kMinPeakCompressed = std::log1p(4.0);

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

// cv::phaseCorrelate on copies: when the images already have an optimal DFT size (128 x 128, say), OpenCV
// multiplies them by the window in place.
cv::Point2d phaseShift(const cv::Mat& a, const cv::Mat& b, const cv::Mat& window, double* response) {
  return cv::phaseCorrelate(a.clone(), b.clone(), window, response);
}

// Centroid (weighted by the image values) and peak of one connected source of a thresholded image.
struct Source {
  double x = 0.0, y = 0.0, peak = 0.0;
};

// The sources of a thresholded, compressed image (0 where faint): 8-connected components of at least
// kMinSourcePixels pixels whose peak reaches `minPeak`; each source counts once, however large.
std::vector<Source> sourcesOf(const cv::Mat& image, double minPeak) {
  constexpr int kMinSourcePixels = 4;
  cv::Mat labels;
  const cv::Mat on = image > 0.0;
  const int n = cv::connectedComponents(on, labels, 8, CV_32S);
  std::vector<Source> acc(static_cast<std::size_t>(std::max(0, n)));
  std::vector<double> sw(acc.size(), 0.0);
  std::vector<int> pixels(acc.size(), 0);
  for (int y = 0; y < image.rows; ++y) {
    const double* row = image.ptr<double>(y);
    const int* lab = labels.ptr<int>(y);
    for (int x = 0; x < image.cols; ++x) {
      if (lab[x] <= 0) continue;
      Source& s = acc[static_cast<std::size_t>(lab[x])];
      s.x += row[x] * x, s.y += row[x] * y, s.peak = std::max(s.peak, row[x]);
      sw[static_cast<std::size_t>(lab[x])] += row[x];
      ++pixels[static_cast<std::size_t>(lab[x])];
    }
  }
  std::vector<Source> out;
  for (std::size_t k = 1; k < acc.size(); ++k)
    if (pixels[k] >= kMinSourcePixels && acc[k].peak >= minPeak && sw[k] > 0)
      out.push_back({acc[k].x / sw[k], acc[k].y / sw[k], acc[k].peak});
  return out;
}

// The stars' consensus offset of `b` relative to `a` (thresholded, compressed images): each bright source of
// `a` is paired with the source of `b` nearest to where `coarse` puts it (within kMatchRadiusPx), and the
// median of the pairs' centroid offsets is the offset. One vote per source, so that a bright moving object
// (a streak, whose pixels all peak alike) counts as one outlier among the stars, not as many votes, and no
// source weighs more for being brighter. False with fewer than 3 pairs.
bool consensusOffset(const cv::Mat& a, const cv::Mat& b, cv::Point2d coarse, double minPeak, cv::Point2d* d) {
  constexpr double kMatchRadiusPx = 3.0;
  const std::vector<Source> sa = sourcesOf(a, minPeak), sb = sourcesOf(b, minPeak);
  std::vector<double> dx, dy;
  for (const Source& s : sa) {
    const Source* best = nullptr;
    double bestD = kMatchRadiusPx;
    for (const Source& t : sb) {
      const double dist = std::hypot(t.x - s.x - coarse.x, t.y - s.y - coarse.y);
      if (dist < bestD) bestD = dist, best = &t;
    }
    if (best) dx.push_back(best->x - s.x), dy.push_back(best->y - s.y);
  }
  if (dx.size() < 3) return false;
  std::nth_element(dx.begin(), dx.begin() + dx.size() / 2, dx.end());
  std::nth_element(dy.begin(), dy.begin() + dy.size() / 2, dy.end());
  *d = {dx[dx.size() / 2], dy[dy.size() / 2]};
  return true;
}

// Refines a rate: stacks of the first and last thirds of the frames at `rate` put the stars at the same
// reference positions when the rate is right. The stacks shift frames by whole pixels, round(v dt_n), so a
// star sits in the stack of frames N at x_ref + mean_N(v_true dt_n - round(v dt_n)): the offset d between
// the thirds' stacks gives v_true = (d + R_b - R_a) / (t_b - t_a), with R the mean integer shift of each
// third (adding d / (t_b - t_a) to `rate` instead would count the same offset again whenever the integer
// shifts do not change). Iterates (the stacks smear less as the rate improves) until the integer shifts
// stay the same.
Velocity refineRate(const FrameCube& cube, Velocity rate, double background, double sigma, double detectSigma,
                    double minResponse, double* response, CancelToken& cancel) {
  const std::size_t nf = cube.frameCount(), third = std::max<std::size_t>(1, nf / 3);
  const auto dt = cube.timeOffsetsS();
  double ta = 0.0, tb = 0.0;
  for (std::size_t n = 0; n < third; ++n)
    ta += dt[n] / third, tb += dt[nf - third + n] / third;
  if (tb <= ta) return rate;
  // Mean integer shift of frames [first, first + third) at rate v along one axis.
  auto meanShift = [&](double v, std::size_t first) {
    double sum = 0.0;
    for (std::size_t n = first; n < first + third; ++n)
      sum += static_cast<double>(std::lround(v * dt[n]));
    return sum / static_cast<double>(third);
  };
  NullProgress none;
  for (int it = 0; it < 4; ++it) {
    const SkyStack a = stackAtSkyRate(cube, rate, background, none, cancel, 0, third);
    const SkyStack b = stackAtSkyRate(cube, rate, background, none, cancel, nf - third, nf);
    cv::Mat window;
    cv::createHanningWindow(window, cv::Size(a.mean.width, a.mean.height), CV_64F);
    double r = 0.0;
    const cv::Mat ia = stackImage(a, detectSigma * sigma), ib = stackImage(b, detectSigma * sigma);
    cv::Point2d d = phaseShift(ia, ib, window, &r);
    if (r < minResponse) break;
    *response = r;
    // The stars' consensus: the phase correlation's sub-pixel peak is pulled by a bright moving object.
    cv::Point2d c;
    if (consensusOffset(ia, ib, d, kMinPeakCompressed, &c)) d = c;
    const Velocity next{(d.x + meanShift(rate.vx, nf - third) - meanShift(rate.vx, 0)) / (tb - ta),
                        (d.y + meanShift(rate.vy, nf - third) - meanShift(rate.vy, 0)) / (tb - ta)};
    bool sameShifts = true;
    for (std::size_t n = 0; n < nf && sameShifts; ++n)
      sameShifts = std::lround(next.vx * dt[n]) == std::lround(rate.vx * dt[n]) &&
                   std::lround(next.vy * dt[n]) == std::lround(rate.vy * dt[n]);
    rate = next;
    if (sameShifts) break;
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
    cv::Point2d d = phaseShift(a.image, b.image, window, &response);
    cv::Point2d c;
    if (consensusOffset(a.image, b.image, d, kMinPeakCompressed, &c)) d = c;
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

#include "st/inject/field.hpp"

#include <algorithm>
#include <cmath>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <map>
#include <mutex>
#include <string>

#include "../common/opencv_threads.hpp"
#include "st/calib/calibration.hpp"
#include "st/common/error.hpp"
#include "st/common/parallel.hpp"
#include "st/psf/psf_star.hpp"
#include "st/sim/samplers.hpp"

namespace st::inject {
namespace {

double medianOf(std::vector<double>& v) {
  if (v.empty()) return 0.0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  double m = *mid;
  if (v.size() % 2 == 0) m = 0.5 * (m + *std::max_element(v.begin(), mid));
  return m;
}

/// 1 where a pixel is masked in any frame of the cube.
std::vector<std::uint8_t> maskedInAnyFrame(const FrameCube& cube) {
  std::vector<std::uint8_t> any(cube.framePixels(), 0);
  if (cube.mask().empty()) return any;
  for (std::size_t n = 0; n < cube.frameCount(); ++n)
    for (std::size_t i = 0; i < any.size(); ++i)
      any[i] |= cube.mask()[n * cube.framePixels() + i];
  return any;
}

psf::Moffat measurePsfOnFrames(const FrameCube& cube, int psfFrames, Field& field, ProgressSink& progress,
                               CancelToken& cancel) {
  const std::size_t count = std::clamp<std::size_t>(static_cast<std::size_t>(std::max(psfFrames, 1)), 1,
                                                    cube.frameCount());
  std::vector<psf::MoffatFit> fits(count);
  std::vector<std::uint8_t> ok(count, 0);
  std::vector<std::string> why(count);
  parallelFor(count, 1, [&](std::size_t k0, std::size_t k1) {
    for (std::size_t k = k0; k < k1; ++k) {
      cancel.throwIfCancelled();
      const std::size_t n = count == 1 ? cube.frameCount() / 2 : k * (cube.frameCount() - 1) / (count - 1);
      Image frame = cube.frameImage(n);
      for (int y = 0; y < frame.height; ++y)
        for (int x = 0; x < frame.width; ++x)
          if (cube.isMasked(n, x, y)) frame.at(x, y) = 0.0f;  // the fit skips exact zeros
      try {
        fits[k] = psf::measurePsf(frame, {}).fit;
        ok[k] = 1;
      } catch (const InputError& e) {
        why[k] = e.what();
      }
      progress.report(0.5 + 0.5 * static_cast<double>(k1) / count, "inject: PSF");
    }
  });
  std::vector<std::size_t> good;
  for (std::size_t n = 0; n < fits.size(); ++n)
    if (ok[n]) good.push_back(n);
  if (good.empty())
    throw InputError("inject: no star usable for the PSF in any frame (" + why.front() +
                     "); give the PSF with --fwhm (and --beta)");
  std::sort(good.begin(), good.end(), [&](std::size_t a, std::size_t b) { return fits[a].fwhm() < fits[b].fwhm(); });
  for (const std::size_t n : good)
    field.psfFwhmPerFramePx.push_back(fits[n].fwhm());
  return fits[good[good.size() / 2]].model;
}

}  // namespace

double residualScale(std::size_t frames) {
  if (frames < 2) throw InputError("residual scale: needs at least 2 frames");
  static std::mutex mutex;
  static std::map<std::size_t, double> cache;
  const std::lock_guard lock(mutex);
  if (auto it = cache.find(frames); it != cache.end()) return it->second;
  sim::Rng rng(sim::streamSeed(20261125, frames));
  sim::NormalPairs normal;
  const std::size_t pixels = std::max<std::size_t>(200, 200000 / frames);
  std::vector<double> column(frames), scratch, residuals;
  residuals.reserve(pixels * frames);
  for (std::size_t k = 0; k < pixels; ++k) {
    for (double& v : column)
      v = normal.next(rng);
    scratch = column;
    const double m = medianOf(scratch);
    for (const double v : column)
      residuals.push_back(std::abs(v - m));
  }
  const double scale = 1.4826 * medianOf(residuals);  // residuals about a median: their own median is ~0
  cache[frames] = scale;
  return scale;
}

Image meshBackground(const Image& image, const std::vector<std::uint8_t>& mask, int meshPx) {
  if (meshPx < 4) throw InputError("mesh background: cell must be >= 4 px, got " + std::to_string(meshPx));
  const int nx = (image.width + meshPx - 1) / meshPx, ny = (image.height + meshPx - 1) / meshPx;
  std::vector<double> cell(static_cast<std::size_t>(nx) * ny, std::nan(""));
  std::vector<double> values, found;
  for (int cy = 0; cy < ny; ++cy)
    for (int cx = 0; cx < nx; ++cx) {
      values.clear();
      for (int y = cy * meshPx; y < std::min(image.height, (cy + 1) * meshPx); ++y)
        for (int x = cx * meshPx; x < std::min(image.width, (cx + 1) * meshPx); ++x) {
          const std::size_t i = static_cast<std::size_t>(y) * image.width + x;
          const float v = image.pixels[i];
          if ((!mask.empty() && mask[i]) || v == 0.0f || !std::isfinite(v)) continue;
          values.push_back(v);
        }
      if (values.size() >= 8) {
        cell[static_cast<std::size_t>(cy) * nx + cx] = medianOf(values);
        found.push_back(cell[static_cast<std::size_t>(cy) * nx + cx]);
      }
    }
  const double fallback = medianOf(found);
  for (double& c : cell)
    if (std::isnan(c)) c = fallback;
  Image bg(image.width, image.height);
  for (int y = 0; y < image.height; ++y) {
    const double fy = std::clamp((y + 0.5) / meshPx - 0.5, 0.0, ny - 1.0);
    const int y0 = std::min(static_cast<int>(fy), ny - 1), y1 = std::min(y0 + 1, ny - 1);
    const double wy = fy - y0;
    for (int x = 0; x < image.width; ++x) {
      const double fx = std::clamp((x + 0.5) / meshPx - 0.5, 0.0, nx - 1.0);
      const int x0 = std::min(static_cast<int>(fx), nx - 1), x1 = std::min(x0 + 1, nx - 1);
      const double wx = fx - x0;
      auto c = [&](int i, int j) { return cell[static_cast<std::size_t>(j) * nx + i]; };
      bg.at(x, y) = static_cast<float>((1 - wy) * ((1 - wx) * c(x0, y0) + wx * c(x1, y0)) +
                                       wy * ((1 - wx) * c(x0, y1) + wx * c(x1, y1)));
    }
  }
  return bg;
}

Field measureField(const FrameCube& cube, const FieldParams& params, ProgressSink& progress,
                   CancelToken& cancel) {
  if (cube.frameCount() < 3)
    throw InputError("inject: needs at least 3 frames to measure the frame-to-frame noise, got " +
                     std::to_string(cube.frameCount()));
  Field f;
  f.width = cube.width();
  f.height = cube.height();
  progress.report(0.0, "inject: median frame");
  const Image median = calib::medianCombine(cube, cancel);
  const std::vector<std::uint8_t> bad = maskedInAnyFrame(cube);
  Image residual = median;
  const Image bg = meshBackground(median, bad, params.meshPx);
  for (std::size_t i = 0; i < residual.size(); ++i)
    residual.pixels[i] = bad[i] ? 0.0f : median.pixels[i] - bg.pixels[i];
  f.medianFrameNoise = psf::robustImageNoise(residual);
  f.mask = bad;
  const double threshold = params.starThresholdSigma * f.medianFrameNoise;
  for (std::size_t i = 0; i < residual.size(); ++i)
    if (residual.pixels[i] > threshold) f.mask[i] = 1;
  f.maskedPixels = static_cast<std::size_t>(std::count(f.mask.begin(), f.mask.end(), 1));
  // Distance of every pixel to the nearest masked one (OpenCV: distance to the nearest zero).
  st::detail::useOpenCvSequentially();
  cv::Mat unmasked(f.height, f.width, CV_8U);
  for (std::size_t i = 0; i < f.mask.size(); ++i)
    unmasked.data[i] = f.mask[i] ? 0 : 1;
  cv::Mat dist;
  if (f.maskedPixels == 0) {
    dist = cv::Mat(f.height, f.width, CV_32F, cv::Scalar(1e9f));
  } else {
    cv::distanceTransform(unmasked, dist, cv::DIST_L2, cv::DIST_MASK_PRECISE, CV_32F);
  }
  f.maskDistancePx.assign(reinterpret_cast<const float*>(dist.data),
                          reinterpret_cast<const float*>(dist.data) + f.mask.size());
  progress.report(0.5, "inject: PSF");
  if (params.psf) {
    f.psf = *params.psf;
  } else {
    f.psf = measurePsfOnFrames(cube, params.psfFrames, f, progress, cancel);
    f.psfMeasured = true;
  }
  progress.report(1.0, "inject: field measured");
  return f;
}

std::vector<double> localFrameNoise(const FrameCube& cube, const std::vector<std::uint8_t>& mask,
                                    const io::PixelRegion& region) {
  const std::size_t nf = cube.frameCount();
  if (nf < 3) throw InputError("local noise: needs at least 3 frames, got " + std::to_string(nf));
  const int xa = std::max(0, region.x0), ya = std::max(0, region.y0);
  const int xb = std::min(cube.width(), region.x0 + region.width);
  const int yb = std::min(cube.height(), region.y0 + region.height);
  std::vector<std::size_t> pixels;
  for (int y = ya; y < yb; ++y)
    for (int x = xa; x < xb; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * cube.width() + x;
      bool usable = mask.empty() || mask[i] == 0;
      for (std::size_t n = 0; usable && n < nf; ++n)
        usable = !cube.isMasked(n, x, y);
      if (usable) pixels.push_back(i);
    }
  if (pixels.size() < 50)
    throw InputError("local noise: only " + std::to_string(pixels.size()) + " usable pixels in the region at (" +
                     std::to_string(region.x0) + ", " + std::to_string(region.y0) + ") of " +
                     std::to_string(region.width) + " x " + std::to_string(region.height) + " px");
  // values[n][k]: frame n at pixel k, its regional median taken out.
  std::vector<std::vector<double>> values(nf, std::vector<double>(pixels.size()));
  std::vector<double> scratch;
  for (std::size_t n = 0; n < nf; ++n) {
    const float* fr = cube.frame(n);
    for (std::size_t k = 0; k < pixels.size(); ++k)
      values[n][k] = fr[pixels[k]];
    scratch = values[n];
    const double level = medianOf(scratch);
    for (double& v : values[n])
      v -= level;
  }
  std::vector<double> column(nf);
  for (std::size_t k = 0; k < pixels.size(); ++k) {
    for (std::size_t n = 0; n < nf; ++n)
      column[n] = values[n][k];
    const double m = medianOf(column);
    for (std::size_t n = 0; n < nf; ++n)
      values[n][k] -= m;
  }
  const double correction = residualScale(nf);
  std::vector<double> sigma(nf);
  for (std::size_t n = 0; n < nf; ++n) {
    scratch = values[n];
    const double med = medianOf(scratch);
    for (double& v : scratch)
      v = std::abs(v - med);
    sigma[n] = 1.4826 * medianOf(scratch) / correction;
  }
  return sigma;
}

}  // namespace st::inject

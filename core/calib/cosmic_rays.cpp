#include "st/calib/cosmic_rays.hpp"

#include <algorithm>
#include <cmath>
#include <mutex>

#include "st/common/parallel.hpp"
#include "st/detect/moving_mask.hpp"
#include "st/detect/sky_stack.hpp"
#include "st/stats/sigma_clip.hpp"

namespace st::calib {
namespace {

// The two frames a frame is compared with: its neighbours, or the next two at either end.
std::pair<std::size_t, std::size_t> neighbours(std::size_t n, std::size_t nf) {
  if (n == 0) return {1, 2};
  if (n + 1 == nf) return {nf - 2, nf - 3};
  return {n - 1, n + 1};
}

// Protected positions (at t_ref, following the sky rate) and the star signal there: the smallest block mean
// above the local background, counts per frame.
struct Protection {
  detect::MovingMask mask;
  std::vector<float> signal;  // on the mask's canvas
  [[nodiscard]] float signalAt(std::size_t n, int x, int y) const {
    const int i = x - mask.shiftX(n) - mask.x0(), j = y - mask.shiftY(n) - mask.y0();
    if (i < 0 || j < 0 || i >= mask.canvasWidth() || j >= mask.canvasHeight()) return 0.0f;
    return signal[static_cast<std::size_t>(j) * mask.canvasWidth() + i];
  }
};

Protection protection(const FrameCube& cube, const CosmicRayParams& params, double sigma,
                      ProgressSink& progress, CancelToken& cancel) {
  detect::MovingMask mask(cube.width(), cube.height(), cube.timeOffsetsS(), params.skyRate);
  const std::size_t nf = cube.frameCount();
  const int blocks = static_cast<int>(std::clamp<std::size_t>(params.protectBlocks, 1, nf));
  std::vector<float> minSnr, minMean;
  for (int b = 0; b < blocks; ++b) {
    SubProgress sub(progress, 0.5 * b / blocks, 0.5 * (b + 1) / blocks);
    const detect::SkyStack s = detect::stackAtSkyRate(cube, params.skyRate, 0.0, sub, cancel, nf * b / blocks,
                                                      nf * (b + 1) / blocks);
    const Image local = detect::meshBackground(s.mean, s.count, 32);
    if (minSnr.empty()) minSnr.assign(s.mean.size(), 1e30f), minMean.assign(s.mean.size(), 1e30f);
    for (std::size_t i = 0; i < s.mean.size(); ++i) {
      const float snr = s.count.pixels[i] > 0 ? static_cast<float>((s.mean.pixels[i] - local.pixels[i]) *
                                                                   std::sqrt(s.count.pixels[i]) / sigma)
                                              : 0.0f;
      minSnr[i] = std::min(minSnr[i], snr);
      minMean[i] = std::min(minMean[i], s.mean.pixels[i] - local.pixels[i]);
    }
  }
  for (int j = 0; j < mask.canvasHeight(); ++j)
    for (int i = 0; i < mask.canvasWidth(); ++i)
      if (minSnr[static_cast<std::size_t>(j) * mask.canvasWidth() + i] >= params.protectSnr)
        mask.set(mask.x0() + i, mask.y0() + j);
  mask.dilate(params.protectDilatePx);
  Protection p{std::move(mask), std::vector<float>(minMean.size(), 0.0f)};
  for (std::size_t i = 0; i < minMean.size(); ++i)
    if (p.mask.canvas()[i]) p.signal[i] = std::max(0.0f, minMean[i]);
  return p;
}

}  // namespace

double noiseFromFrameDifferences(const FrameCube& cube) {
  const std::size_t nf = cube.frameCount();
  if (nf < 2) return 0.0;
  std::vector<double> sig;
  const auto& mask = cube.mask();
  const std::size_t np = cube.framePixels();
  for (std::size_t k = 0; k < 3; ++k) {
    const std::size_t a = (nf - 1) * k / 3, b = a + 1;
    std::vector<float> d;
    d.reserve(np);
    for (std::size_t i = 0; i < np; ++i) {
      if (!mask.empty() && (mask[a * np + i] || mask[b * np + i])) continue;
      d.push_back(cube.frame(b)[i] - cube.frame(a)[i]);
    }
    if (d.size() > 1)
      sig.push_back(stats::sigmaClipSymmetric(d.data(), d.size(), 5.0).sigma / std::sqrt(2.0));
  }
  if (sig.empty()) return 0.0;
  std::sort(sig.begin(), sig.end());
  return sig[sig.size() / 2];
}

CosmicRayResult removeCosmicRays(FrameCube& cube, const CosmicRayParams& params, ProgressSink& progress,
                                 CancelToken& cancel) {
  CosmicRayResult out;
  const std::size_t nf = cube.frameCount();
  out.perFrame.assign(nf, 0);
  if (nf < 3) return out;
  out.sigma = noiseFromFrameDifferences(cube);
  if (!(out.sigma > 0.0)) return out;
  const Protection prot = protection(cube, params, out.sigma, progress, cancel);
  out.protectedPixels = prot.mask.count();
  const int w = cube.width(), h = cube.height();
  const std::size_t np = cube.framePixels();
  const auto& mask = cube.mask();
  const float* px = cube.pixels().data();
  auto excess = [&](std::size_t n, std::size_t i) {
    const auto [a, b] = neighbours(n, nf);
    return px[n * np + i] - std::max(px[a * np + i], px[b * np + i]);
  };
  // On a protected star a hit must also exceed the star's own signal there: seeing and photon noise make a
  // star pixel vary far more than the sky.
  auto eligible = [&](std::size_t n, int x, int y, float ex) {
    const std::size_t i = static_cast<std::size_t>(y) * w + x;
    if (!mask.empty() && mask[n * np + i]) return false;
    return !prot.mask.covers(n, x, y) || ex > params.protectedExcess * prot.signalAt(n, x, y);
  };
  const float thr = static_cast<float>(params.thresholdSigma * out.sigma);
  std::mutex m;
  // Pass 1, read-only: seeds.
  parallelFor(nf, 4, [&](std::size_t n0, std::size_t n1) {
    std::vector<std::uint64_t> local;
    for (std::size_t n = n0; n < n1; ++n) {
      cancel.throwIfCancelled();
      const auto [a, b] = neighbours(n, nf);
      const float* f = px + n * np;
      const float* fa = px + a * np;
      const float* fb = px + b * np;
      for (std::size_t i = 0; i < np; ++i) {
        const float ex = f[i] - std::max(fa[i], fb[i]);
        if (ex <= thr) continue;
        if (eligible(n, static_cast<int>(i % w), static_cast<int>(i / w), ex)) local.push_back(n * np + i);
      }
    }
    std::lock_guard lock(m);
    out.pixels.insert(out.pixels.end(), local.begin(), local.end());
    progress.report(0.5 + 0.4 * static_cast<double>(n1) / nf, "cosmic rays");
  });
  // Pass 2, read-only: grow by the 8-neighbours above growSigma (twice, for short tracks).
  const float grow = static_cast<float>(params.growSigma * out.sigma);
  std::sort(out.pixels.begin(), out.pixels.end());
  for (int pass = 0; pass < 2; ++pass) {
    std::vector<std::uint64_t> added;
    for (std::uint64_t p : out.pixels) {
      const std::size_t n = p / np, i = p % np;
      const int x = static_cast<int>(i % w), y = static_cast<int>(i / w);
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int qx = x + dx, qy = y + dy;
          if ((dx == 0 && dy == 0) || qx < 0 || qy < 0 || qx >= w || qy >= h) continue;
          const std::size_t q = static_cast<std::size_t>(qy) * w + qx;
          const float ex = excess(n, q);
          if (ex > grow && eligible(n, qx, qy, ex)) added.push_back(n * np + q);
        }
    }
    out.pixels.insert(out.pixels.end(), added.begin(), added.end());
    std::sort(out.pixels.begin(), out.pixels.end());
    out.pixels.erase(std::unique(out.pixels.begin(), out.pixels.end()), out.pixels.end());
  }
  // Pass 3: fill. Reference values come from frames not yet modified where possible: compute all fills first.
  std::vector<float> fill(out.pixels.size(), 0.0f);
  if (params.fill == CosmicRayParams::Fill::TimeNeighbours) {
    for (std::size_t k = 0; k < out.pixels.size(); ++k) {
      const std::size_t n = out.pixels[k] / np, i = out.pixels[k] % np;
      const auto [a, b] = neighbours(n, nf);
      fill[k] = 0.5f * (px[a * np + i] + px[b * np + i]);
    }
  }
  float* wpx = cube.pixels().data();
  for (std::size_t k = 0; k < out.pixels.size(); ++k) {
    wpx[out.pixels[k]] = fill[k];
    ++out.perFrame[out.pixels[k] / np];
  }
  out.total = out.pixels.size();
  progress.report(1.0, "cosmic rays");
  return out;
}

void zeroPixels(FrameCube& cube, const std::vector<std::uint64_t>& pixels) {
  float* px = cube.pixels().data();
  for (std::uint64_t p : pixels)
    if (p < cube.pixels().size()) px[p] = 0.0f;
}

}  // namespace st::calib

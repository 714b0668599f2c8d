#include "st/detect/star_subtraction.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <mutex>
#include <numeric>
#include <utility>
#include <vector>

#include "st/common/parallel.hpp"

namespace st::detect {
namespace {

constexpr double kPi = 3.14159265358979323846;

double lanczos3(double t) {
  t = std::fabs(t);
  if (t < 1e-9) return 1.0;
  if (t >= 3.0) return 0.0;
  const double a = kPi * t;
  return 3.0 * std::sin(a) * std::sin(a / 3.0) / (a * a);
}

// Canvas positions (indices into region's canvas) that the region sets, listed once.
std::vector<int> regionPixels(const MovingMask& region) {
  std::vector<int> out;
  const auto& c = region.canvas();
  for (int i = 0; i < static_cast<int>(c.size()); ++i)
    if (c[i]) out.push_back(i);
  return out;
}

// Whether any of p[0, n) is non-zero (8 bytes at a time).
bool anySet(const std::uint8_t* p, int n) {
  std::uint64_t acc = 0;
  int i = 0;
  for (; i + 8 <= n; i += 8) {
    std::uint64_t u;
    std::memcpy(&u, p + i, sizeof u);
    acc |= u;
  }
  for (; i < n; ++i)
    acc |= p[i];
  return acc != 0;
}

}  // namespace

int lanczos3Weights(double f, double w[6]) {
  // Sampling at p = f: taps at k = b - 2 .. b + 3 with b = floor(f), weight L(f - k).
  const int b = static_cast<int>(std::floor(f));
  double sum = 0.0;
  for (int i = 0; i < 6; ++i) {
    w[i] = lanczos3(f - (b - 2 + i));
    sum += w[i];
  }
  for (int i = 0; i < 6; ++i)
    w[i] /= sum;
  return b - 2;
}

std::optional<StarTemplatePlan> planStarTemplate(const FrameCube& cube, const MovingMask& region,
                                                 const StarSubtractionParams& params) {
  const std::size_t nf = cube.frameCount();
  if (region.empty() || nf < 4 || region.frameCount() != nf) return std::nullopt;
  StarTemplatePlan plan;
  plan.targets = regionPixels(region);
  if (plan.targets.empty()) return std::nullopt;
  // The template covers the region grown by the interpolation's reach (6 x 6 taps: up to 3 px along each
  // axis, so 3 sqrt(2) on the diagonals), so that its edge is subtracted too. A disc of 3 px left the
  // corner taps of the region's rim without a template, and those pixels were zeroed: a ring around every
  // star in 30-70% of the frames (paper-neo seed 24: 8% of its asteroid's PSF^2-weighted track).
  MovingMask grown = region;
  grown.dilate(5);
  plan.positions = regionPixels(grown);
  const std::vector<double> dt = cube.timeOffsetsS();
  const double window = params.windowFraction * cube.timeSpanS();
  // Blocks of consecutive times, equal counts.
  std::vector<std::size_t> order(nf);
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return dt[a] < dt[b]; });
  const int nb = std::max(1, std::min<int>(params.blocks, static_cast<int>(nf)));
  plan.blocks = nb;
  plan.blockOf.assign(nf, 0);
  std::vector<double> t0(nb, 1e300), t1(nb, -1e300);
  for (std::size_t k = 0; k < nf; ++k) {
    const int b = static_cast<int>(k * nb / nf);
    plan.blockOf[order[k]] = b;
    t0[b] = std::min(t0[b], dt[order[k]]);
    t1[b] = std::max(t1[b], dt[order[k]]);
  }
  // Block c is excluded from block b's template when their time ranges come within the window.
  plan.excluded.assign(static_cast<std::size_t>(nb) * nb, 0);
  bool any = false;
  for (int b = 0; b < nb; ++b)
    for (int c = 0; c < nb; ++c) {
      const bool ex = t0[c] <= t1[b] + window && t1[c] >= t0[b] - window;
      plan.excluded[static_cast<std::size_t>(b) * nb + c] = ex ? 1 : 0;
      any = any || !ex;
    }
  if (!any) return std::nullopt;
  return plan;
}

std::pair<double, double> starTemplateFractionalOffset(const MovingMask& region, const FrameCube& cube,
                                                       std::size_t n, double dt) {
  const Velocity v = region.rate();
  const FrameInfo& f = cube.info()[n];
  return {f.offsetXPx + v.vx * dt - region.shiftX(n), f.offsetYPx + v.vy * dt - region.shiftY(n)};
}

double starResidualVerdict(double r2, double s2, double samples, const StarSubtractionParams& params) {
  if (samples < params.minExcessSamples || !(s2 > 0.0)) return 0.0;
  // The ratio of S samples scatters by sqrt(2 / S) about 1 (chi-square: a heavy upper tail).
  const double ratio = r2 / s2;
  if (ratio <= 1.0 + params.excessSignificance * std::sqrt(2.0 / samples)) return 0.0;
  if (ratio > params.maxVarianceRatio) return -1.0;
  return 1.0 / std::sqrt(ratio);
}

StarSubtraction subtractStarTemplate(FrameCube& cube, const MovingMask& region, const Image* sigma,
                                     const StarSubtractionParams& params, ProgressSink& progress,
                                     CancelToken& cancel) {
  StarSubtraction out;
  const std::size_t nf = cube.frameCount();
  const std::optional<StarTemplatePlan> plan = planStarTemplate(cube, region, params);
  if (!plan) return out;
  const std::vector<int>& targets = plan->targets;
  const std::vector<int>& pix = plan->positions;
  const std::vector<double> dt = cube.timeOffsetsS();
  const int nb = plan->blocks;
  const std::vector<int>& blockOf = plan->blockOf;
  auto excluded = [&](int b, int c) { return plan->excluded[static_cast<std::size_t>(b) * nb + c] != 0; };

  const int w = cube.width(), h = cube.height(), cw = region.canvasWidth();
  const std::size_t np = pix.size();
  const auto& mask = cube.mask();
  const std::size_t fp = cube.framePixels();

  // The canvas columns and rows of the grown region's and the targets' positions, divided out once.
  std::vector<int> pixI(np), pixJ(np), tgtI(targets.size()), tgtJ(targets.size());
  for (std::size_t k = 0; k < np; ++k)
    pixI[k] = pix[k] % cw, pixJ[k] = pix[k] / cw;
  for (std::size_t k = 0; k < targets.size(); ++k)
    tgtI[k] = targets[k] % cw, tgtJ[k] = targets[k] / cw;

  // Per-block sums and counts of the resampled frames at the region's canvas positions.
  std::vector<std::vector<float>> sum(nb, std::vector<float>(np, 0.0f));
  std::vector<std::vector<float>> cnt(nb, std::vector<float>(np, 0.0f));
  SubProgress accumulate(progress, 0.0, 0.5);
  parallelFor(static_cast<std::size_t>(nb), 1, [&](std::size_t b0, std::size_t b1) {
    std::vector<int> maskedRows(static_cast<std::size_t>(h) + 1, 0);
    for (std::size_t b = b0; b < b1; ++b) {
      for (std::size_t n = 0; n < nf; ++n) {
        if (blockOf[n] != static_cast<int>(b)) continue;
        cancel.throwIfCancelled();
        const auto [fx, fy] = starTemplateFractionalOffset(region, cube, n, dt[n]);
        double wx[6], wy[6];
        const int ox = lanczos3Weights(fx, wx), oy = lanczos3Weights(fy, wy);
        const float* f = cube.frame(n);
        const std::uint8_t* m = mask.empty() ? nullptr : mask.data() + n * fp;
        const int sx = region.shiftX(n), sy = region.shiftY(n);
        // Rows of this frame with a masked pixel, counted cumulatively: taps on rows without one need no
        // test.
        maskedRows[0] = 0;
        for (int y = 0; y < h; ++y)
          maskedRows[y + 1] = maskedRows[y] + (m && anySet(m + static_cast<std::size_t>(y) * w, w) ? 1 : 0);
        for (std::size_t k = 0; k < np; ++k) {
          // Taps at x + ox .. x + ox + 5 (and the same in y).
          const int x = region.x0() + pixI[k] + sx + ox, y = region.y0() + pixJ[k] + sy + oy;
          if (x < 0 || y < 0 || x + 5 >= w || y + 5 >= h) continue;
          if (maskedRows[y + 6] == maskedRows[y]) {  // the same sums as below, no tap masked
            double v = 0.0;
            for (int j = 0; j < 6; ++j) {
              const float* row = f + static_cast<std::size_t>(y + j) * w + x;
              double r = 0.0;
              for (int i = 0; i < 6; ++i)
                r += wx[i] * row[i];
              v += wy[j] * r;
            }
            sum[b][k] += static_cast<float>(v);
            cnt[b][k] += 1.0f;
            continue;
          }
          double v = 0.0;
          bool bad = false;
          for (int j = 0; j < 6 && !bad; ++j) {
            const std::size_t row = static_cast<std::size_t>(y + j) * w;
            double r = 0.0;
            for (int i = 0; i < 6; ++i) {
              const std::size_t q = row + x + i;
              if (m && m[q]) {
                bad = true;
                break;
              }
              r += wx[i] * f[q];
            }
            v += wy[j] * r;
          }
          if (bad) continue;
          sum[b][k] += static_cast<float>(v);
          cnt[b][k] += 1.0f;
        }
      }
      accumulate.report(static_cast<double>(b1) / nb, "star templates");
    }
  });

  // One template per block over the canvas (0 where it has no samples), with its validity.
  const std::size_t canvasSize = static_cast<std::size_t>(cw) * region.canvasHeight();
  std::vector<std::vector<float>> tmpl(nb);
  std::vector<std::vector<std::uint8_t>> valid(nb);
  double framesSum = 0.0;
  std::size_t framesN = 0;
  for (int b = 0; b < nb; ++b) {
    tmpl[b].assign(canvasSize, 0.0f);
    valid[b].assign(canvasSize, 0);
    for (std::size_t k = 0; k < np; ++k) {
      double s = 0.0, c = 0.0;
      for (int o = 0; o < nb; ++o)
        if (!excluded(b, o)) {
          s += sum[o][k];
          c += cnt[o][k];
        }
      if (c >= params.minTemplateFrames) {
        tmpl[b][pix[k]] = static_cast<float>(s / c);
        valid[b][pix[k]] = 1;
        framesSum += c;
        ++framesN;
      }
    }
  }
  sum.clear();
  cnt.clear();
  out.meanTemplateFrames = framesN ? framesSum / framesN : 0.0;

  // Subtract, in each frame, the template resampled at the frame's offset (taps must all be valid; where
  // they are not, the pixel is zeroed: a star seen only within one window has no template). The residuals'
  // variance at each sky position is summed against the background's (sigma) for the excess test.
  const int ch = region.canvasHeight();
  const bool withSigma = sigma && sigma->size() == fp;
  std::vector<std::size_t> perFrame(nf, 0), zeroedPerFrame(nf, 0);
  std::vector<double> r2(targets.size(), 0.0), s2(targets.size(), 0.0);
  std::vector<float> samples(targets.size(), 0.0f);
  std::mutex reduce;
  SubProgress subtract(progress, 0.5, 1.0);
  parallelFor(nf, 8, [&](std::size_t n0, std::size_t n1) {
    std::vector<double> lr2(withSigma ? targets.size() : 0, 0.0), ls2(lr2.size(), 0.0);
    std::vector<float> lsamples(lr2.size(), 0.0f);
    for (std::size_t n = n0; n < n1; ++n) {
      cancel.throwIfCancelled();
      const int b = blockOf[n];
      const auto [fx, fy] = starTemplateFractionalOffset(region, cube, n, dt[n]);
      // Template at canvas position X - f: base X, offset -f.
      double wx[6], wy[6];
      const int ox = lanczos3Weights(-fx, wx), oy = lanczos3Weights(-fy, wy);
      float* f = cube.frame(n);
      const int sx = region.shiftX(n), sy = region.shiftY(n);
      const float* t = tmpl[b].data();
      const std::uint8_t* ok = valid[b].data();
      for (std::size_t k = 0; k < targets.size(); ++k) {
        const int i = tgtI[k], j = tgtJ[k];
        const int x = region.x0() + i + sx, y = region.y0() + j + sy;
        if (x < 0 || y < 0 || x >= w || y >= h) continue;
        float& px = f[static_cast<std::size_t>(y) * w + x];
        bool bad = i + ox < 0 || j + oy < 0 || i + ox + 5 >= cw || j + oy + 5 >= ch;
        double v = 0.0;
        for (int jj = 0; jj < 6 && !bad; ++jj) {
          const std::size_t row = static_cast<std::size_t>(j + oy + jj) * cw;
          double r = 0.0;
          for (int ii = 0; ii < 6; ++ii) {
            const std::size_t q = row + i + ox + ii;
            if (!ok[q]) {
              bad = true;
              break;
            }
            r += wx[ii] * t[q];
          }
          v += wy[jj] * r;
        }
        if (bad) {
          if (px != 0.0f) ++zeroedPerFrame[n];
          px = 0.0f;
          continue;
        }
        px -= static_cast<float>(v);
        ++perFrame[n];
        if (withSigma && px != 0.0f) {
          const double sg = sigma->pixels[static_cast<std::size_t>(y) * w + x];
          if (sg > 0) {
            lr2[k] += static_cast<double>(px) * px;
            ls2[k] += sg * sg;
            lsamples[k] += 1.0f;
          }
        }
      }
    }
    if (withSigma) {
      std::lock_guard<std::mutex> lock(reduce);
      for (std::size_t k = 0; k < targets.size(); ++k) {
        r2[k] += lr2[k];
        s2[k] += ls2[k];
        samples[k] += lsamples[k];
      }
    }
    subtract.report(static_cast<double>(n1) / nf, "subtract star templates");
  });
  out.pixelsSubtracted = std::accumulate(perFrame.begin(), perFrame.end(), std::size_t{0});
  out.pixelsZeroed = std::accumulate(zeroedPerFrame.begin(), zeroedPerFrame.end(), std::size_t{0});
  // Sky positions where what is left varies more than the background allows (the star's photon noise, its
  // seeing changes, the interpolation's error): whitened, or masked like the cores when the excess is large.
  out.excess = MovingMask(cube, region.rate());
  if (withSigma) {
    // The whitened positions and their factors, listed once: the per-frame pass visits only those.
    std::vector<std::pair<int, float>> whiten;
    for (std::size_t k = 0; k < targets.size(); ++k) {
      const double verdict = starResidualVerdict(r2[k], s2[k], samples[k], params);
      if (verdict < 0.0)
        out.excess.set(region.x0() + targets[k] % cw, region.y0() + targets[k] / cw);
      else if (verdict > 0.0)
        whiten.emplace_back(targets[k], static_cast<float>(verdict));
    }
    out.whitenedPositions = whiten.size();
    out.excessPositions = out.excess.count();
    out.excess.dilate(1);
    if (!whiten.empty())
      parallelFor(nf, 8, [&](std::size_t n0, std::size_t n1) {
        for (std::size_t n = n0; n < n1; ++n) {
          float* f = cube.frame(n);
          const int sx = region.shiftX(n), sy = region.shiftY(n);
          for (const auto& [pos, factor] : whiten) {
            const int x = region.x0() + pos % cw + sx, y = region.y0() + pos / cw + sy;
            if (x >= 0 && y >= 0 && x < w && y < h) f[static_cast<std::size_t>(y) * w + x] *= factor;
          }
        }
      });
  }
  out.applied = true;
  return out;
}

}  // namespace st::detect

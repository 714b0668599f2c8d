#include "st/stats/background.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "st/common/error.hpp"
#include "st/common/parallel.hpp"

namespace st::stats {
namespace {

std::vector<std::size_t> evenlySpaced(std::size_t total, std::size_t wanted) {
  std::vector<std::size_t> idx;
  if (total == 0) return idx;
  const std::size_t n = std::min(total, std::max<std::size_t>(1, wanted));
  idx.reserve(n);
  for (std::size_t i = 0; i < n; ++i)
    idx.push_back(n == total ? i : (i * total) / n);
  return idx;
}

// Per-pixel clip of one row: buf holds nf x w samples (frame-major), NaN where left out. Performs exactly
// the arithmetic of sigmaClip (same shift, same summation order) for each column, vectorised over columns.
struct RowClip {
  std::vector<double> mean, sigma;
  std::vector<std::size_t> count;
  std::vector<double> hi;  ///< the threshold that defined the final clipped set (samples <= hi)
};

RowClip clipRow(const std::vector<float>& buf, std::size_t nf, int w, double xi) {
  RowClip r;
  r.mean.assign(w, 0.0);
  r.sigma.assign(w, 0.0);
  r.count.assign(w, 0);
  std::vector<double> shift(w, 0.0), hi(w, std::numeric_limits<double>::infinity());
  std::vector<std::size_t> prev(w, std::numeric_limits<std::size_t>::max());
  std::vector<std::uint8_t> done(w, 0);
  for (int x = 0; x < w; ++x) {
    done[x] = 1;
    for (std::size_t n = 0; n < nf; ++n) {
      const float v = buf[n * w + x];
      if (!std::isnan(v)) {
        shift[x] = v;
        done[x] = 0;
        break;
      }
    }
  }
  std::vector<double> s(w), ss(w);
  std::vector<std::size_t> c(w);
  // The samples' bound for this pass: hi, or -inf for a finished column (and NaN fails any comparison), so
  // the pass has no branch and vectorises; the same sums in the same order as testing `done` per sample.
  std::vector<double> bound(w);
  int remaining = static_cast<int>(std::count(done.begin(), done.end(), 0));
  for (int it = 0; it < 100 && remaining > 0; ++it) {
    std::fill(s.begin(), s.end(), 0.0);
    std::fill(ss.begin(), ss.end(), 0.0);
    std::fill(c.begin(), c.end(), 0);
    for (int x = 0; x < w; ++x)
      bound[x] = done[x] ? -std::numeric_limits<double>::infinity() : hi[x];
    for (std::size_t n = 0; n < nf; ++n) {
      const float* row = buf.data() + n * w;
      for (int x = 0; x < w; ++x) {
        const double y = row[x];
        const bool in = y <= bound[x];
        const double d = in ? y - shift[x] : 0.0;
        c[x] += in;
        s[x] += d;
        ss[x] += d * d;
      }
    }
    for (int x = 0; x < w; ++x) {
      if (done[x]) continue;
      r.count[x] = c[x];
      if (c[x] == 0) {
        done[x] = 1;
        --remaining;
        continue;
      }
      const double m = s[x] / static_cast<double>(c[x]);
      r.mean[x] = shift[x] + m;
      r.sigma[x] =
          c[x] > 1 ? std::sqrt(std::max(0.0, (ss[x] - s[x] * m) / static_cast<double>(c[x] - 1))) : 0.0;
      if (c[x] == prev[x]) {
        done[x] = 1;
        --remaining;
        continue;
      }
      prev[x] = c[x];
      hi[x] = r.mean[x] + xi * r.sigma[x];
    }
  }
  r.hi = std::move(hi);
  return r;
}

}  // namespace

ClipStats globalBackground(const FrameCube& cube, const GlobalBackgroundParams& params) {
  if (cube.empty()) throw InputError("global background: the frame cube has no frames");
  const auto frames = evenlySpaced(cube.frameCount(), params.frames);
  std::vector<float> samples;
  samples.reserve(frames.size() * cube.framePixels());
  const auto& mask = cube.mask();
  for (std::size_t n : frames) {
    const float* f = cube.frame(n);
    const std::size_t base = n * cube.framePixels();
    for (std::size_t i = 0; i < cube.framePixels(); ++i) {
      if ((!mask.empty() && mask[base + i]) || !std::isfinite(f[i])) continue;
      samples.push_back(f[i]);
    }
  }
  if (samples.empty()) {
    throw InputError("global background: every pixel of the " + std::to_string(frames.size()) +
                     " frames used is masked (first file: " + cube.info().front().file + ")");
  }
  return sigmaClip(samples.data(), samples.size(), params.xi);
}

namespace {

// The per-pixel clip of every row: fills out.level, out.sigma, out.filled, out.sigmaN; calls
// onRow(y, buf, frames, clip) for each row after its clip (buf: the row's samples of the frames used).
template <class OnRow>
Background clipRows(const FrameCube& cube, const BackgroundParams& params, const MovingMask* exclude,
                    ProgressSink& progress, CancelToken& cancel, const OnRow& onRow) {
  Background out;
  out.global = globalBackground(cube, params.global);
  const int w = cube.width(), h = cube.height();
  const auto frames = evenlySpaced(cube.frameCount(), params.maxFrames);
  out.framesUsed = frames.size();
  out.level = Image(w, h);
  out.sigma = Image(w, h);
  const double strong = out.global.mean + params.strongSignalXi * out.global.sigma;
  const auto& mask = cube.mask();
  const float kNaN = std::numeric_limits<float>::quiet_NaN();
  std::vector<std::uint8_t> valid(static_cast<std::size_t>(w) * h, 0);
  parallelFor(static_cast<std::size_t>(h), 4, [&](std::size_t y0, std::size_t y1) {
    std::vector<float> buf(frames.size() * static_cast<std::size_t>(w));
    std::vector<std::uint8_t> excluded(static_cast<std::size_t>(w), 0);
    for (std::size_t y = y0; y < y1; ++y) {
      cancel.throwIfCancelled();
      for (std::size_t k = 0; k < frames.size(); ++k) {
        const std::size_t n = frames[k];
        const std::size_t off = n * cube.framePixels() + y * w;
        const float* src = cube.pixels().data() + off;
        const std::uint8_t* m = mask.empty() ? nullptr : mask.data() + off;
        if (exclude) exclude->coveredRow(n, static_cast<int>(y), excluded.data());
        float* dst = buf.data() + k * w;
        for (int x = 0; x < w; ++x) {
          const float v = src[x];
          const bool out1 = !std::isfinite(v) || v > strong || (m && m[x]) || excluded[x];
          dst[x] = out1 ? kNaN : v;
        }
      }
      const RowClip r = clipRow(buf, frames.size(), w, params.xi);
      for (int x = 0; x < w; ++x) {
        const std::size_t i = y * w + x;
        const bool ok = r.count[x] >= params.minSamples;
        valid[i] = ok;
        out.level.pixels[i] = static_cast<float>(ok ? r.mean[x] : out.global.mean);
        out.sigma.pixels[i] = static_cast<float>(ok ? r.sigma[x] : out.global.sigma);
      }
      onRow(y, buf, frames, r, valid.data() + y * w, out.level.pixels.data() + y * w);
      if (y % 16 == 0) progress.report(static_cast<double>(y) / h, "per-pixel background");
    }
  });
  double sumVar = 0.0;
  std::size_t nValid = 0;
  for (std::size_t i = 0; i < valid.size(); ++i) {
    if (!valid[i]) continue;
    sumVar += static_cast<double>(out.sigma.pixels[i]) * out.sigma.pixels[i];
    ++nValid;
  }
  out.pixelsFilled = valid.size() - nValid;
  out.filled.resize(valid.size());
  for (std::size_t i = 0; i < valid.size(); ++i)
    out.filled[i] = !valid[i];
  if (nValid == 0) {
    throw InputError("per-pixel background: no pixel has " + std::to_string(params.minSamples) +
                     " unmasked background samples (frames used: " + std::to_string(frames.size()) + ")");
  }
  out.sigmaN = std::sqrt(sumVar / static_cast<double>(nValid));
  if (params.noiseMap) out.noiseMap = boxSmooth(out.sigma, params.noiseMapBoxPx, valid);
  progress.report(1.0, "per-pixel background");
  return out;
}

}  // namespace

Background estimateBackground(const FrameCube& cube, const BackgroundParams& params,
                              const MovingMask* exclude, ProgressSink& progress,
                              CancelToken& cancel) {
  return clipRows(cube, params, exclude, progress, cancel,
                  [](std::size_t, const std::vector<float>&, const std::vector<std::size_t>&, const RowClip&,
                     const std::uint8_t*, const float*) {});
}

Background subtractPixelBackground(FrameCube& cube, const BackgroundParams& params,
                                   const MovingMask* exclude, ProgressSink& progress,
                                   CancelToken& cancel) {
  const int w = cube.width();
  const std::size_t nf = cube.frameCount(), np = cube.framePixels();
  const std::vector<double> t = cube.timeOffsetsS();
  const bool sorted = std::is_sorted(t.begin(), t.end());
  const double window = sorted ? params.moverWindowFraction * cube.timeSpanS() : 0.0;
  const auto& mask = cube.mask();
  // For every frame n, the used frames [lo, hi) (indices into the evenly spaced set) within +-window of it.
  const auto used = evenlySpaced(nf, params.maxFrames);
  std::vector<std::size_t> lo(nf, 0), hi(nf, 0);
  if (window > 0.0) {
    for (std::size_t n = 0; n < nf; ++n) {
      lo[n] = static_cast<std::size_t>(
          std::lower_bound(used.begin(), used.end(), n,
                           [&](std::size_t k, std::size_t m) { return t[k] < t[m] - window; }) -
          used.begin());
      hi[n] = static_cast<std::size_t>(
          std::upper_bound(used.begin(), used.end(), n,
                           [&](std::size_t m, std::size_t k) { return t[m] + window < t[k]; }) -
          used.begin());
    }
  }
  float* pix = cube.pixels().data();
  auto onRow = [&](std::size_t y, const std::vector<float>& buf, const std::vector<std::size_t>& frames,
                   const RowClip& r, const std::uint8_t* validRow, const float* levelRow) {
    const std::size_t nk = frames.size();
    // Running sums of the clipped samples inside the current window, per column.
    std::vector<double> winS(w, 0.0), total(w, 0.0);
    std::vector<std::size_t> winC(w, 0), totalC(w, 0);
    // Adds sample k's clipped values (NaN and those above the clip bound count 0) to sum and count, times
    // sign; branch-free, so it vectorises.
    auto accumulate = [&](std::size_t k, std::vector<double>& sum, std::vector<std::size_t>& count, int sign) {
      const float* row = buf.data() + k * w;
      for (int x = 0; x < w; ++x) {
        const double v = row[x];
        const bool in = v <= r.hi[x];
        sum[x] += in ? sign * v : 0.0;
        count[x] += in ? static_cast<std::size_t>(sign) : 0;
      }
    };
    for (std::size_t k = 0; k < nk; ++k)
      accumulate(k, total, totalC, 1);
    std::size_t curLo = 0, curHi = 0;
    std::vector<float> level(w);
    for (std::size_t n = 0; n < nf; ++n) {
      if (window > 0.0) {
        for (; curHi < hi[n]; ++curHi)
          accumulate(curHi, winS, winC, 1);
        for (; curLo < lo[n]; ++curLo)
          accumulate(curLo, winS, winC, -1);
      }
      for (int x = 0; x < w; ++x) {
        // Short sequences: 15 frames less the 7 of a middle frame's window leave 8; a third of the clipped
        // samples (at least 4) still beats taking a mover's own flux into its background.
        const std::size_t c = totalC[x] - winC[x];
        const std::size_t need = std::min(params.minSamples, std::max<std::size_t>(4, totalC[x] / 3));
        level[x] =
            validRow[x] && c >= need ? static_cast<float>((total[x] - winS[x]) / double(c)) : levelRow[x];
      }
      const std::size_t off = n * np + y * w;
      float* f = pix + off;
      for (int x = 0; x < w; ++x) {
        const float v = f[x] - level[x];
        f[x] = ((!mask.empty() && mask[off + x]) || !std::isfinite(v)) ? 0.0f : v;
      }
    }
  };
  return clipRows(cube, params, exclude, progress, cancel, onRow);
}

void subtractBackground(FrameCube& cube, const Image& level, ProgressSink& progress, CancelToken& cancel) {
  if (level.width != cube.width() || level.height != cube.height()) {
    throw InputError("background of " + std::to_string(level.width) + "x" + std::to_string(level.height) +
                     " does not match frames of " + std::to_string(cube.width()) + "x" +
                     std::to_string(cube.height()));
  }
  const std::size_t np = cube.framePixels();
  const auto& mask = cube.mask();
  parallelFor(cube.frameCount(), 8, [&](std::size_t n0, std::size_t n1) {
    for (std::size_t n = n0; n < n1; ++n) {
      cancel.throwIfCancelled();
      float* f = cube.frame(n);
      const std::uint8_t* m = mask.empty() ? nullptr : mask.data() + n * np;
      for (std::size_t i = 0; i < np; ++i) {
        const float v = f[i] - level.pixels[i];
        f[i] = ((m && m[i]) || !std::isfinite(v)) ? 0.0f : v;
      }
    }
    progress.report(static_cast<double>(n1) / cube.frameCount(), "subtract background");
  });
}

Image boxSmooth(const Image& image, int box, const std::vector<std::uint8_t>& valid) {
  const int w = image.width, h = image.height, r = std::max(0, box / 2);
  // Separable sums of value and weight; O(1) per pixel per pass with running sums.
  std::vector<double> v(image.size()), wt(image.size());
  for (std::size_t i = 0; i < image.size(); ++i) {
    const double ok = valid.empty() || valid[i] ? 1.0 : 0.0;
    v[i] = ok * image.pixels[i];
    wt[i] = ok;
  }
  auto pass = [&](std::vector<double>& a, bool alongX) {
    std::vector<double> out(a.size());
    const int len = alongX ? w : h, lines = alongX ? h : w;
    for (int l = 0; l < lines; ++l) {
      auto at = [&](int k) -> double& {
        return alongX ? a[static_cast<std::size_t>(l) * w + k] : a[static_cast<std::size_t>(k) * w + l];
      };
      std::vector<double> prefix(len + 1, 0.0);
      for (int k = 0; k < len; ++k)
        prefix[k + 1] = prefix[k] + at(k);
      for (int k = 0; k < len; ++k) {
        const double s = prefix[std::min(len, k + r + 1)] - prefix[std::max(0, k - r)];
        (alongX ? out[static_cast<std::size_t>(l) * w + k] : out[static_cast<std::size_t>(k) * w + l]) = s;
      }
    }
    a.swap(out);
  };
  pass(v, true);
  pass(v, false);
  pass(wt, true);
  pass(wt, false);
  Image out(w, h);
  for (std::size_t i = 0; i < out.size(); ++i)
    out.pixels[i] = wt[i] > 0 ? static_cast<float>(v[i] / wt[i]) : 0.0f;
  return out;
}

}  // namespace st::stats

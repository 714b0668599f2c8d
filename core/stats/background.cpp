#include "st/stats/background.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <tuple>
#include <vector>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#endif

#include "st/common/error.hpp"
#include "st/common/parallel.hpp"
#include "st/stats/strong_signal_cut.hpp"

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

// The per-pixel clip of one row's columns.
struct RowClip {
  std::vector<double> mean, sigma;
  std::vector<std::size_t> count;
  std::vector<double> hi;  ///< the threshold that defined the final clipped set (samples <= hi)
};

// One pass of the clip over columns [xa, xa + B) of the row's nf samples: count, sum and sum of squares
// (about shift) of the samples <= bound (NaN and a finished column's -inf bound admit none).
template <int B>
void clipPassScalar(const float* buf, std::size_t nf, int w, int xa, const double* bound, const double* shift,
                    double* s, double* ss, std::size_t* c) {
  const float* row = buf + xa;
  for (std::size_t n = 0; n < nf; ++n, row += w) {
    for (int j = 0; j < B; ++j) {
      const double y = row[j];
      const bool in = y <= bound[j];
      const double d = in ? y - shift[j] : 0.0;
      c[j] += in;
      s[j] += d;
      ss[j] += d * d;
    }
  }
}

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define ST_BACKGROUND_AVX2 1
// The same pass for 16 columns with AVX2: the same operations per sample in the same order (an excluded
// sample adds +0.0 and 0, as the scalar select does; no fused multiply-add).
__attribute__((target("avx2"))) void clipPass16Avx2(const float* buf, std::size_t nf, int w, int xa,
                                                    const double* bound, const double* shift, double* s,
                                                    double* ss, std::size_t* c) {
  __m256d b[4], sh[4], sv[4], ssv[4];
  __m256i cv[4];
  for (int q = 0; q < 4; ++q) {
    b[q] = _mm256_loadu_pd(bound + 4 * q);
    sh[q] = _mm256_loadu_pd(shift + 4 * q);
    sv[q] = _mm256_setzero_pd();
    ssv[q] = _mm256_setzero_pd();
    cv[q] = _mm256_setzero_si256();
  }
  const float* row = buf + xa;
  for (std::size_t n = 0; n < nf; ++n, row += w) {
    const __m256 lo = _mm256_loadu_ps(row), hi = _mm256_loadu_ps(row + 8);
    const __m256d y[4] = {
        _mm256_cvtps_pd(_mm256_castps256_ps128(lo)), _mm256_cvtps_pd(_mm256_extractf128_ps(lo, 1)),
        _mm256_cvtps_pd(_mm256_castps256_ps128(hi)), _mm256_cvtps_pd(_mm256_extractf128_ps(hi, 1))};
    for (int q = 0; q < 4; ++q) {
      const __m256d in = _mm256_cmp_pd(y[q], b[q], _CMP_LE_OQ);
      const __m256d d = _mm256_and_pd(_mm256_sub_pd(y[q], sh[q]), in);
      cv[q] = _mm256_sub_epi64(cv[q], _mm256_castpd_si256(in));
      sv[q] = _mm256_add_pd(sv[q], d);
      ssv[q] = _mm256_add_pd(ssv[q], _mm256_mul_pd(d, d));
    }
  }
  for (int q = 0; q < 4; ++q) {
    _mm256_storeu_pd(s + 4 * q, sv[q]);
    _mm256_storeu_pd(ss + 4 * q, ssv[q]);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(c + 4 * q), cv[q]);
  }
}

bool haveAvx2() {
  static const bool has = __builtin_cpu_supports("avx2") != 0;
  return has;
}
#endif

// The clip of columns [xa, xa + B) of the row, each column with exactly the iterations of sigmaClip; a
// block stops when its own columns have converged (a column's result does not depend on the others', so
// the blocks give the row's clip exactly, with the block's samples in L1/L2 for every pass).
template <int B>
void clipColumns(const float* buf, std::size_t nf, int w, int xa, double xi, double* mean, double* sigma,
                 std::size_t* count, double* hiOut) {
  double shift[B], hi[B], s[B], ss[B], bound[B];
  std::size_t prev[B], c[B];
  bool done[B];
  int remaining = 0;
  for (int j = 0; j < B; ++j) {
    mean[j] = 0.0;
    sigma[j] = 0.0;
    count[j] = 0;
    shift[j] = 0.0;
    hi[j] = std::numeric_limits<double>::infinity();
    prev[j] = std::numeric_limits<std::size_t>::max();
    done[j] = true;
    for (std::size_t n = 0; n < nf; ++n) {
      const float v = buf[n * w + xa + j];
      if (!std::isnan(v)) {
        shift[j] = v;
        done[j] = false;
        break;
      }
    }
    remaining += !done[j];
  }
  for (int it = 0; it < 100 && remaining > 0; ++it) {
    for (int j = 0; j < B; ++j)
      bound[j] = done[j] ? -std::numeric_limits<double>::infinity() : hi[j];
    bool passed = false;
#ifdef ST_BACKGROUND_AVX2
    if constexpr (B == 16) {
      if (haveAvx2()) {
        clipPass16Avx2(buf, nf, w, xa, bound, shift, s, ss, c);
        passed = true;
      }
    }
#endif
    if (!passed) {
      std::fill_n(s, B, 0.0);
      std::fill_n(ss, B, 0.0);
      std::fill_n(c, B, std::size_t{0});
      clipPassScalar<B>(buf, nf, w, xa, bound, shift, s, ss, c);
    }
    for (int j = 0; j < B; ++j) {
      if (done[j]) continue;
      count[j] = c[j];
      if (c[j] == 0) {
        done[j] = true;
        --remaining;
        continue;
      }
      const double m = s[j] / static_cast<double>(c[j]);
      mean[j] = shift[j] + m;
      sigma[j] =
          c[j] > 1 ? std::sqrt(std::max(0.0, (ss[j] - s[j] * m) / static_cast<double>(c[j] - 1))) : 0.0;
      if (c[j] == prev[j]) {
        done[j] = true;
        --remaining;
        continue;
      }
      prev[j] = c[j];
      hi[j] = mean[j] + xi * sigma[j];
    }
  }
  for (int j = 0; j < B; ++j)
    hiOut[j] = hi[j];
}

constexpr int kClipBlock = 16;

// Per-pixel clip of one row: buf holds nf x w samples (frame-major), NaN where left out. sigmaClip's
// iterations for each column (same shift and bounds; each column's samples summed in frame order), in
// blocks of columns.
RowClip clipRow(const std::vector<float>& buf, std::size_t nf, int w, double xi) {
  RowClip r;
  r.mean.assign(w, 0.0);
  r.sigma.assign(w, 0.0);
  r.count.assign(w, 0);
  r.hi.assign(w, std::numeric_limits<double>::infinity());
  int x = 0;
  for (; x + kClipBlock <= w; x += kClipBlock)
    clipColumns<kClipBlock>(buf.data(), nf, w, x, xi, &r.mean[x], &r.sigma[x], &r.count[x], &r.hi[x]);
  for (; x < w; ++x)
    clipColumns<1>(buf.data(), nf, w, x, xi, &r.mean[x], &r.sigma[x], &r.count[x], &r.hi[x]);
  return r;
}

// One frame row of the per-pixel clip's buffer: NaN where the sample is left out (not finite, masked or
// excluded); the strong signals are cut after (cutStrongAboveMedian).
__attribute__((target_clones("avx2", "default"))) void gatherRow(float* __restrict dst,
                                                                 const float* __restrict src,
                                                                 const std::uint8_t* __restrict m,
                                                                 const std::uint8_t* __restrict excluded,
                                                                 int w) {
  const float kNaN = std::numeric_limits<float>::quiet_NaN();
  const float kMax = std::numeric_limits<float>::max();
  for (int x = 0; x < w; ++x) {
    const float v = src[x];
    const bool keep = (std::fabs(v) <= kMax) & (m[x] == 0) & (excluded[x] == 0);
    dst[x] = keep ? v : kNaN;
  }
}

// Adds the row's samples at or below the clip bound hi (NaN counts 0) to sum and count, times sign. The
// counts are doubles (exact integers) so the window's mean needs no integer conversion.
void accumulateClippedScalar(const float* row, const double* hi, double* sum, double* count, int x0, int w,
                             int sign) {
  for (int x = x0; x < w; ++x) {
    const double v = row[x];
    const bool in = v <= hi[x];
    sum[x] += in ? sign * v : 0.0;
    count[x] += in ? sign : 0;
  }
}

// The background of one frame row from the running window sums: the clipped mean outside the window where
// enough samples remain (need: +inf for a pixel without a measured background), else the row's level.
void windowLevelScalar(const double* total, const double* totalC, const double* winS, const double* winC,
                       const double* need, const float* levelRow, float* level, int x0, int w) {
  for (int x = x0; x < w; ++x) {
    const double c = totalC[x] - winC[x];
    level[x] = c >= need[x] ? static_cast<float>((total[x] - winS[x]) / c) : levelRow[x];
  }
}

#ifdef ST_BACKGROUND_AVX2
__attribute__((target("avx2"))) void accumulateClippedAvx2(const float* row, const double* hi, double* sum,
                                                           double* count, int w, int sign) {
  const __m256d sg = _mm256_set1_pd(sign);
  int x = 0;
  for (; x + 4 <= w; x += 4) {
    const __m256d v = _mm256_cvtps_pd(_mm_loadu_ps(row + x));
    const __m256d in = _mm256_cmp_pd(v, _mm256_loadu_pd(hi + x), _CMP_LE_OQ);
    _mm256_storeu_pd(sum + x,
                     _mm256_add_pd(_mm256_loadu_pd(sum + x), _mm256_and_pd(_mm256_mul_pd(sg, v), in)));
    _mm256_storeu_pd(count + x, _mm256_add_pd(_mm256_loadu_pd(count + x), _mm256_and_pd(sg, in)));
  }
  accumulateClippedScalar(row, hi, sum, count, x, w, sign);
}

__attribute__((target("avx2"))) void windowLevelAvx2(const double* total, const double* totalC,
                                                     const double* winS, const double* winC,
                                                     const double* need, const float* levelRow, float* level,
                                                     int w) {
  int x = 0;
  for (; x + 4 <= w; x += 4) {
    const __m256d c = _mm256_sub_pd(_mm256_loadu_pd(totalC + x), _mm256_loadu_pd(winC + x));
    const __m256d mean =
        _mm256_div_pd(_mm256_sub_pd(_mm256_loadu_pd(total + x), _mm256_loadu_pd(winS + x)), c);
    const __m256d keep = _mm256_cmp_pd(c, _mm256_loadu_pd(need + x), _CMP_GE_OQ);
    const __m256d fallback = _mm256_cvtps_pd(_mm_loadu_ps(levelRow + x));  // exact, and back below
    _mm_storeu_ps(level + x, _mm256_cvtpd_ps(_mm256_blendv_pd(fallback, mean, keep)));
  }
  windowLevelScalar(total, totalC, winS, winC, need, levelRow, level, x, w);
}
#endif

void accumulateClipped(const float* row, const double* hi, double* sum, double* count, int w, int sign) {
#ifdef ST_BACKGROUND_AVX2
  if (haveAvx2()) return accumulateClippedAvx2(row, hi, sum, count, w, sign);
#endif
  accumulateClippedScalar(row, hi, sum, count, 0, w, sign);
}

void windowLevel(const double* total, const double* totalC, const double* winS, const double* winC,
                 const double* need, const float* levelRow, float* level, int w) {
#ifdef ST_BACKGROUND_AVX2
  if (haveAvx2()) return windowLevelAvx2(total, totalC, winS, winC, need, levelRow, level, w);
#endif
  windowLevelScalar(total, totalC, winS, winC, need, levelRow, level, 0, w);
}

// f -= level, 0 where masked or not finite.
__attribute__((target_clones("avx2", "default"))) void subtractLevel(float* __restrict f,
                                                                     const float* __restrict level,
                                                                     const std::uint8_t* __restrict m,
                                                                     int w) {
  const float kMax = std::numeric_limits<float>::max();
  for (int x = 0; x < w; ++x) {
    const float v = f[x] - level[x];
    f[x] = (m[x] == 0) & (std::fabs(v) <= kMax) ? v : 0.0f;
  }
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
  // Strong signals: samples above the pixel's own median + strongSignalXi x the global sigma
  // (cutStrongAboveMedian).
  const double strongOffset = params.strongSignalXi * out.global.sigma;
  const auto& mask = cube.mask();
  std::vector<std::uint8_t> valid(static_cast<std::size_t>(w) * h, 0);
  parallelFor(static_cast<std::size_t>(h), 4, [&](std::size_t y0, std::size_t y1) {
    std::vector<float> buf(frames.size() * static_cast<std::size_t>(w)), col;
    std::vector<std::uint8_t> excluded(static_cast<std::size_t>(w), 0),
        noMask(static_cast<std::size_t>(w), 0);
    for (std::size_t y = y0; y < y1; ++y) {
      cancel.throwIfCancelled();
      for (std::size_t k = 0; k < frames.size(); ++k) {
        const std::size_t n = frames[k];
        const std::size_t off = n * cube.framePixels() + y * w;
        const float* src = cube.pixels().data() + off;
        const std::uint8_t* m = mask.empty() ? noMask.data() : mask.data() + off;
        if (exclude) exclude->coveredRow(n, static_cast<int>(y), excluded.data());
        gatherRow(buf.data() + k * w, src, m, excluded.data(), w);
      }
      cutStrongAboveMedian(buf.data(), frames.size(), w, strongOffset, col);
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
                              const MovingMask* exclude, ProgressSink& progress, CancelToken& cancel) {
  return clipRows(cube, params, exclude, progress, cancel,
                  [](std::size_t, const std::vector<float>&, const std::vector<std::size_t>&, const RowClip&,
                     const std::uint8_t*, const float*) {});
}

Background subtractPixelBackground(FrameCube& cube, const BackgroundParams& params, const MovingMask* exclude,
                                   ProgressSink& progress, CancelToken& cancel) {
  const int w = cube.width();
  const std::size_t nf = cube.frameCount(), np = cube.framePixels();
  const std::vector<double> t = cube.timeOffsetsS();
  const auto& mask = cube.mask();
  // For every frame n, the used frames [lo, hi) (indices into the evenly spaced set) within +-window of it.
  const PixelBackgroundWindows windows = pixelBackgroundWindows(cube, params);
  const double window = windows.windowS;
  std::vector<std::size_t> lo(nf, 0), hi(nf, 0);
  for (std::size_t n = 0; n < nf; ++n)
    std::tie(lo[n], hi[n]) = windows.window(n, t);
  float* pix = cube.pixels().data();
  auto onRow = [&](std::size_t y, const std::vector<float>& buf, const std::vector<std::size_t>& frames,
                   const RowClip& r, const std::uint8_t* validRow, const float* levelRow) {
    const std::size_t nk = frames.size();
    // Running sums of the clipped samples inside the current window, per column.
    std::vector<double> winS(w, 0.0), total(w, 0.0);
    std::vector<double> winC(w, 0.0), totalC(w, 0.0);  // counts, exact in doubles
    for (std::size_t k = 0; k < nk; ++k)
      accumulateClipped(buf.data() + k * w, r.hi.data(), total.data(), totalC.data(), w, 1);
    // Short sequences: 15 frames less the 7 of a middle frame's window leave 8; a third of the clipped
    // samples (at least 4) still beats taking a mover's own flux into its background.
    std::vector<double> need(w);
    for (int x = 0; x < w; ++x)
      need[x] =
          validRow[x]
              ? static_cast<double>(std::min(
                    params.minSamples, std::max<std::size_t>(4, static_cast<std::size_t>(totalC[x]) / 3)))
              : std::numeric_limits<double>::infinity();
    std::size_t curLo = 0, curHi = 0;
    std::vector<float> level(levelRow, levelRow + w);
    const std::vector<std::uint8_t> noMask(mask.empty() ? static_cast<std::size_t>(w) : 0, 0);
    bool changed = true;
    for (std::size_t n = 0; n < nf; ++n) {
      if (window > 0.0) {
        for (; curHi < hi[n]; ++curHi, changed = true)
          accumulateClipped(buf.data() + curHi * w, r.hi.data(), winS.data(), winC.data(), w, 1);
        for (; curLo < lo[n]; ++curLo, changed = true)
          accumulateClipped(buf.data() + curLo * w, r.hi.data(), winS.data(), winC.data(), w, -1);
      }
      if (changed)
        windowLevel(total.data(), totalC.data(), winS.data(), winC.data(), need.data(), levelRow,
                    level.data(), w);
      changed = false;
      const std::size_t off = n * np + y * w;
      subtractLevel(pix + off, level.data(), mask.empty() ? noMask.data() : mask.data() + off, w);
    }
  };
  return clipRows(cube, params, exclude, progress, cancel, onRow);
}

PixelBackgroundWindows PixelBackgroundWindows::evenlyOver(std::size_t frameCount, std::size_t setSize,
                                                          double windowS, std::size_t minOutside,
                                                          double clipXi) {
  PixelBackgroundWindows w;
  w.frames = evenlySpaced(frameCount, setSize);
  w.windowS = windowS;
  w.minOutside = minOutside;
  w.clipXi = clipXi;
  return w;
}

PixelBackgroundWindows pixelBackgroundWindows(const FrameCube& cube, const BackgroundParams& params) {
  const std::vector<double> t = cube.timeOffsetsS();
  PixelBackgroundWindows w = PixelBackgroundWindows::evenlyOver(
      cube.frameCount(), params.maxFrames,
      std::is_sorted(t.begin(), t.end()) ? params.moverWindowFraction * cube.timeSpanS() : 0.0, 0, params.xi);
  // subtractPixelBackground's need with every sample of the pixel clipped in.
  w.minOutside = std::min(params.minSamples, std::max<std::size_t>(4, w.frames.size() / 3));
  return w;
}

std::pair<std::size_t, std::size_t> PixelBackgroundWindows::window(std::size_t n,
                                                                   const std::vector<double>& t) const {
  if (!(windowS > 0.0) || n >= t.size()) return {0, 0};
  const auto lo = std::lower_bound(frames.begin(), frames.end(), n,
                                   [&](std::size_t k, std::size_t m) { return t[k] < t[m] - windowS; });
  const auto hi = std::upper_bound(frames.begin(), frames.end(), n,
                                   [&](std::size_t m, std::size_t k) { return t[m] + windowS < t[k]; });
  return {static_cast<std::size_t>(lo - frames.begin()), static_cast<std::size_t>(hi - frames.begin())};
}

std::pair<std::size_t, std::size_t> PixelBackgroundWindows::leftOut(std::size_t n,
                                                                    const std::vector<double>& t) const {
  const auto [a, b] = window(n, t);
  if (b <= a || frames.size() - (b - a) < minOutside) return {0, 0};
  return {a, b};
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
  // The lines are independent (each its own prefix sums): on every core, the same sums as one thread's
  // (serial, the four passes took 12 ms of the GPU pipeline's main thread for a 512^2 image).
  auto pass = [&](std::vector<double>& a, bool alongX) {
    std::vector<double> out(a.size());
    const int len = alongX ? w : h, lines = alongX ? h : w;
    parallelFor(static_cast<std::size_t>(lines), 32, [&](std::size_t l0, std::size_t l1) {
      std::vector<double> prefix(len + 1, 0.0);
      for (std::size_t l = l0; l < l1; ++l) {
        auto at = [&](int k) -> double& {
          return alongX ? a[l * w + k] : a[static_cast<std::size_t>(k) * w + l];
        };
        for (int k = 0; k < len; ++k)
          prefix[k + 1] = prefix[k] + at(k);
        for (int k = 0; k < len; ++k) {
          const double s = prefix[std::min(len, k + r + 1)] - prefix[std::max(0, k - r)];
          (alongX ? out[l * w + k] : out[static_cast<std::size_t>(k) * w + l]) = s;
        }
      }
    });
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

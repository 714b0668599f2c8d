#include "star_footprint.hpp"

#include <algorithm>
#include <cmath>
#include <optional>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#endif

#include "st/common/parallel.hpp"
#include "st/detect/sky_stack.hpp"
#include "st/psf/moffat.hpp"

namespace st::detect::detail {
namespace {

constexpr double kArmSignificance = 2.0;  // a spike/bleed sample counts while its SNR is at least this
constexpr int kArmGapPx = 10;             // an arm ends after this many insignificant samples in a row

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define ST_FOOTPRINT_AVX2 1
bool haveAvx2() {
  static const bool has = __builtin_cpu_supports("avx2") != 0;
  return has;
}

// filteredSnr's pixels x0, x0 + 1, ... of row y while a block of 16 fits before xEnd (every tap inside the
// row): per pixel the same products and sums in the same order as the scalar loop. Returns the next x.
__attribute__((target("avx2"))) int filteredSnrInteriorAvx2(const float* rc, const float* cnt,
                                                            const double* k, int w, int h, int r, int y,
                                                            int x0, int xEnd, double sigma, float* out) {
  const int kw = 2 * r + 1;
  const int j0 = std::max(-r, -y), j1 = std::min(r, h - 1 - y);
  const __m256d sg = _mm256_set1_pd(sigma), zero = _mm256_setzero_pd();
  int x = x0;
  for (; x + 16 <= xEnd; x += 16) {
    __m256d num[4], den[4];
    for (int q = 0; q < 4; ++q)
      num[q] = den[q] = _mm256_setzero_pd();
    for (int j = j0; j <= j1; ++j) {
      const std::size_t row = static_cast<std::size_t>(y + j) * w;
      const double* kr = k + static_cast<std::size_t>(j + r) * kw + r;
      for (int i = -r; i <= r; ++i) {
        const __m256d kv = _mm256_set1_pd(kr[i]);
        const __m256d k2 = _mm256_mul_pd(kv, kv);
        const float* pr = rc + row + x + i;
        const float* pc = cnt + row + x + i;
        const __m256 r0 = _mm256_loadu_ps(pr), r1 = _mm256_loadu_ps(pr + 8);
        const __m256 c0 = _mm256_loadu_ps(pc), c1 = _mm256_loadu_ps(pc + 8);
        const __m256d rv[4] = {
            _mm256_cvtps_pd(_mm256_castps256_ps128(r0)), _mm256_cvtps_pd(_mm256_extractf128_ps(r0, 1)),
            _mm256_cvtps_pd(_mm256_castps256_ps128(r1)), _mm256_cvtps_pd(_mm256_extractf128_ps(r1, 1))};
        const __m256d cv[4] = {
            _mm256_cvtps_pd(_mm256_castps256_ps128(c0)), _mm256_cvtps_pd(_mm256_extractf128_ps(c0, 1)),
            _mm256_cvtps_pd(_mm256_castps256_ps128(c1)), _mm256_cvtps_pd(_mm256_extractf128_ps(c1, 1))};
        for (int q = 0; q < 4; ++q) {
          num[q] = _mm256_add_pd(num[q], _mm256_mul_pd(kv, rv[q]));
          den[q] = _mm256_add_pd(den[q], _mm256_mul_pd(k2, cv[q]));
        }
      }
    }
    for (int q = 0; q < 4; ++q) {
      const __m256d snr = _mm256_div_pd(num[q], _mm256_mul_pd(sg, _mm256_sqrt_pd(den[q])));
      const __m256d pos = _mm256_cmp_pd(den[q], zero, _CMP_GT_OQ);
      float* o = out + static_cast<std::size_t>(y) * w + x + 4 * q;
      const __m128 prev = _mm_loadu_ps(o);
      _mm_storeu_ps(
          o, _mm_blendv_ps(prev, _mm256_cvtpd_ps(snr),
                           _mm_castsi128_ps(_mm256_cvtpd_epi32(_mm256_and_pd(pos, _mm256_set1_pd(-1.0))))));
    }
  }
  return x;
}
#endif

}  // namespace

std::vector<float> filteredSnr(const Image& resid, const Image& count, double sigma, double fwhmPx,
                               const SkyStackCache::SnrProvider* device) {
  const int w = resid.width, h = resid.height;
  std::vector<float> out(resid.size(), 0.0f);
  if (sigma <= 0 || w == 0) return out;
  const psf::Moffat m = psf::Moffat::fromFwhm(fwhmPx, 4.0);
  const int r = std::max(1, static_cast<int>(std::ceil(1.5 * fwhmPx)));
  const int kw = 2 * r + 1;
  std::vector<double> k(static_cast<std::size_t>(kw) * kw);
  for (int j = -r; j <= r; ++j)
    for (int i = -r; i <= r; ++i)
      k[static_cast<std::size_t>(j + r) * kw + (i + r)] = m(i, j);
  std::vector<float> rc(resid.size());
  parallelFor(rc.size(), std::size_t{1} << 16, [&](std::size_t i0, std::size_t i1) {
    for (std::size_t i = i0; i < i1; ++i)
      rc[i] = resid.pixels[i] * count.pixels[i];
  });
  if (device) {
    const FilteredSnrInputs in{rc.data(), count.pixels.data(), w, h, k.data(), r, sigma};
    if (std::optional<std::vector<float>> made = (*device)(in); made && made->size() == out.size())
      return std::move(*made);
  }
  parallelFor(static_cast<std::size_t>(h), 16, [&](std::size_t y0, std::size_t y1) {
    for (int y = static_cast<int>(y0); y < static_cast<int>(y1); ++y) {
      auto pixel = [&](int x) {
        double num = 0.0, den = 0.0;
        for (int j = std::max(-r, -y); j <= std::min(r, h - 1 - y); ++j) {
          const std::size_t row = static_cast<std::size_t>(y + j) * w;
          const double* kr = &k[static_cast<std::size_t>(j + r) * kw + r];
          for (int i = std::max(-r, -x); i <= std::min(r, w - 1 - x); ++i) {
            num += kr[i] * rc[row + x + i];
            den += kr[i] * kr[i] * count.pixels[row + x + i];
          }
        }
        if (den > 0)
          out[static_cast<std::size_t>(y) * w + x] = static_cast<float>(num / (sigma * std::sqrt(den)));
      };
      // Columns whose kernel lies inside the row: 16 at a time on the AVX2 path (each pixel's taps summed in
      // the same order as pixel(x), so the same values); the edge columns one by one.
      int x = 0;
      for (; x < std::min(r, w); ++x)
        pixel(x);
#ifdef ST_FOOTPRINT_AVX2
      if (haveAvx2())
        x = filteredSnrInteriorAvx2(rc.data(), count.pixels.data(), k.data(), w, h, r, y, x, w - r, sigma,
                                    out.data());
#endif
      for (; x < w; ++x)
        pixel(x);
    }
  });
  return out;
}

std::vector<SkyStackCache::Range> halfRanges(std::size_t frames) {
  return {{0, frames / 2}, {frames / 2, frames}};
}

HalfStacks halfStacks(const FrameCube& cube, Velocity skyRate, double background, const Image& local,
                      double sigma, double fwhmPx, SkyStackCache& stacks, CancelToken& cancel) {
  HalfStacks out;
  const std::vector<SkyStackCache::Range> ranges = halfRanges(cube.frameCount());
  NullProgress none;
  for (int k = 0; k < 2; ++k) {
    const auto [first, last] = ranges[static_cast<std::size_t>(k)];
    const SkyStack& h = stacks.stack(cube, skyRate, background, none, cancel, first, last);
    const Image resid = residualWhereCounted(h.mean, h.count, local);
    (k == 0 ? out.first : out.second) = filteredSnr(resid, h.count, sigma, fwhmPx, stacks.snrProvider());
    (k == 0 ? out.countFirst : out.countSecond) = h.count;
  }
  return out;
}

bool HalfStacks::isStatic(int peak, int cw, double fwhmPx, double maxShiftPx) const {
  const int radiusPx = static_cast<int>(std::ceil(fwhmPx)) + 1;
  const double ca = countFirst.pixels[peak], cb = countSecond.pixels[peak];
  if (std::min(ca, cb) < 0.2 * (ca + cb)) return true;
  const double z = (first[peak] * std::sqrt(cb) - second[peak] * std::sqrt(ca)) / std::sqrt(ca + cb);
  if (std::abs(z) > 3.0) return false;
  const int ch = static_cast<int>(first.size()) / cw, px = peak % cw, py = peak / cw;
  int pa = peak, pb = peak;
  for (int y = std::max(0, py - radiusPx); y <= std::min(ch - 1, py + radiusPx); ++y)
    for (int x = std::max(0, px - radiusPx); x <= std::min(cw - 1, px + radiusPx); ++x) {
      if ((x - px) * (x - px) + (y - py) * (y - py) > radiusPx * radiusPx) continue;
      const int i = y * cw + x;
      if (first[i] > first[pa]) pa = i;
      if (second[i] > second[pb]) pb = i;
    }
  // The peaks locate the source to about FWHM / SNR: the allowed shift grows for faint halves.
  const double allowed = maxShiftPx + 1.5 * fwhmPx / std::max(1.0, std::min<double>(first[pa], second[pb]));
  return std::hypot(pa % cw - pb % cw, pa / cw - pb / cw) <= allowed;
}

Image excludeSources(const Image& count, const std::vector<float>& snr, const std::vector<float>& snrF,
                     double level, int growPx) {
  const int w = count.width, h = count.height;
  std::vector<std::uint8_t> rows(count.size(), 0);
  // Grown along rows (a task writes only its rows), then along columns (only its columns).
  parallelFor(static_cast<std::size_t>(h), 16, [&](std::size_t y0, std::size_t y1) {
    for (std::size_t y = y0; y < y1; ++y)
      for (int x = 0; x < w; ++x) {
        const std::size_t i = y * w + x;
        if (snr[i] >= level || snrF[i] >= level)
          for (int k = std::max(0, x - growPx); k <= std::min(w - 1, x + growPx); ++k)
            rows[y * w + k] = 1;
      }
  });
  Image out = count;
  parallelFor(static_cast<std::size_t>(w), 64, [&](std::size_t x0, std::size_t x1) {
    for (int y = 0; y < h; ++y)
      for (std::size_t x = x0; x < x1; ++x)
        if (rows[static_cast<std::size_t>(y) * w + x])
          for (int j = std::max(0, y - growPx); j <= std::min(h - 1, y + growPx); ++j)
            out.pixels[static_cast<std::size_t>(j) * w + x] = 0.0f;
  });
  return out;
}

double wingRadiusPx(double flux, double fwhmPx, double beta, double frames, double sigma) {
  if (flux <= 0 || sigma <= 0 || frames <= 0) return 0.0;
  const psf::Moffat m = psf::Moffat::fromFwhm(fwhmPx, beta);
  const double peak = flux / m.integral();                // counts per frame at the centre
  const double ratio = peak * std::sqrt(frames) / sigma;  // peak over one stack sigma
  if (ratio <= 1.0) return 0.0;
  return m.radius * std::sqrt(std::pow(ratio, 1.0 / beta) - 1.0);
}

void setDisc(MovingMask& mask, double x, double y, double r) {
  // No disc at all for r <= 0: the caller decides what a star without a radius gets (findStaticSources).
  if (!(r > 0.0)) return;
  const int ri = static_cast<int>(std::ceil(r));
  const int cx = static_cast<int>(std::lround(x)), cy = static_cast<int>(std::lround(y));
  for (int dy = -ri; dy <= ri; ++dy)
    for (int dx = -ri; dx <= ri; ++dx)
      if (dx * dx + dy * dy <= r * r) mask.set(cx + dx, cy + dy);
}

int maskSpikes(MovingMask& mask, const Image& resid, const Image& count, double sigma, int x0, int y0,
               const Star& star, int coreRadiusPx, int halfWidthPx) {
  const int w = resid.width, h = resid.height;
  const int cx = static_cast<int>(std::lround(star.x)) - x0, cy = static_cast<int>(std::lround(star.y)) - y0;
  const int dirs[4][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}};
  int longest = 0;
  for (const auto& d : dirs) {
    int last = 0;
    for (int s = 1; s - last <= kArmGapPx; ++s) {
      double sum = 0.0, n = 0.0;
      bool inside = false;
      for (int q = -1; q <= 1; ++q) {  // a 3 px band across the arm
        const int x = cx + d[0] * s + d[1] * q, y = cy + d[1] * s + d[0] * q;
        if (x < 0 || y < 0 || x >= w || y >= h) continue;
        inside = true;
        const std::size_t i = static_cast<std::size_t>(y) * w + x;
        sum += resid.pixels[i] * count.pixels[i];
        n += count.pixels[i];
      }
      if (!inside) break;
      if (n > 0 && sum / (sigma * std::sqrt(n)) >= kArmSignificance) last = s;
    }
    const int len = std::max(last + halfWidthPx, coreRadiusPx);
    longest = std::max(longest, len);
    for (int s = 0; s <= len; ++s)
      for (int q = -halfWidthPx; q <= halfWidthPx; ++q)
        mask.set(cx + x0 + d[0] * s + d[1] * q, cy + y0 + d[1] * s + d[0] * q);
  }
  return longest;
}

int maskBleed(MovingMask& mask, const Image& resid, const Image& count, double sigma, int x0, int y0,
              const Star& star, int halfWidthPx) {
  const int w = resid.width, h = resid.height;
  const int cy = static_cast<int>(std::lround(star.y)) - y0;
  int longest = 0;
  for (int col : star.bleedColumns) {
    const int x = col - x0;
    if (x < 0 || x >= w || cy < 0 || cy >= h) continue;
    int lo = cy, hi = cy;
    for (int dir : {1, -1}) {
      int last = 0;
      for (int s = 1; s - last <= kArmGapPx; ++s) {
        const int y = cy + dir * s;
        if (y < 0 || y >= h) break;
        const std::size_t i = static_cast<std::size_t>(y) * w + x;
        if (count.pixels[i] > 0 && resid.pixels[i] * std::sqrt(count.pixels[i]) / sigma >= kArmSignificance)
          last = s;
      }
      (dir > 0 ? hi : lo) = cy + dir * (last + halfWidthPx);
    }
    longest = std::max(longest, hi - lo + 1);
    for (int y = lo; y <= hi; ++y)
      for (int q = -halfWidthPx; q <= halfWidthPx; ++q)
        mask.set(col + q, y + y0);
  }
  return longest;
}

}  // namespace st::detect::detail

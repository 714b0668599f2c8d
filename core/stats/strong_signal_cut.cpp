#include "st/stats/strong_signal_cut.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#define ST_STRONG_CUT_AVX2 1
#endif

namespace st::stats {
namespace {

#ifdef ST_STRONG_CUT_AVX2
bool haveAvx2() {
  static const bool has = __builtin_cpu_supports("avx2") != 0;
  return has;
}
#endif

// The largest float <= t (+inf for NaN): for a finite float v, v > t (as doubles) is v > floatAtOrBelow(t).
float floatAtOrBelow(double t) {
  float f = std::isnan(t) ? std::numeric_limits<float>::infinity() : static_cast<float>(t);
  if (static_cast<double>(f) > t) f = std::nextafter(f, -std::numeric_limits<float>::infinity());
  return f;
}

// cutStrongAboveMedian of columns [x0, w), each column gathered and selected in (nth_element): the path
// without AVX2 and for the columns after the last 16.
void cutStrongAboveMedianFrom(float* buf, std::size_t nf, int w, int x0, double offset,
                              std::vector<float>& col) {
  const float kNaN = std::numeric_limits<float>::quiet_NaN();
  constexpr int kBlock = 16;  // columns gathered together (their samples share cache lines)
  col.resize(nf * kBlock);
  for (int xa = x0; xa < w; xa += kBlock) {
    const int nb = std::min(kBlock, w - xa);
    std::size_t c[kBlock] = {};
    for (std::size_t n = 0; n < nf; ++n) {
      const float* row = buf + n * w + xa;
      for (int j = 0; j < nb; ++j) {
        const float v = row[j];
        if (!std::isnan(v)) col[j * nf + c[j]++] = v;
      }
    }
    float cut[kBlock];
    for (int j = 0; j < nb; ++j) {
      cut[j] = std::numeric_limits<float>::infinity();
      if (c[j] == 0) continue;
      float* b = col.data() + j * nf;
      std::nth_element(b, b + (c[j] - 1) / 2, b + c[j]);
      cut[j] = floatAtOrBelow(static_cast<double>(b[(c[j] - 1) / 2]) + offset);
    }
    for (std::size_t n = 0; n < nf; ++n) {
      float* row = buf + n * w + xa;
      for (int j = 0; j < nb; ++j)
        if (row[j] > cut[j]) row[j] = kNaN;
    }
  }
}

#ifdef ST_STRONG_CUT_AVX2
// The lower medians of columns [xa, xa + 16) of the buffer (nf x w, NaN left out) by bisection over the
// floats' order-preserving integer keys, 8 columns to a register: exactly the value nth_element gives (-0
// and +0 aside, which compare equal), ~10x faster than gathering each column and selecting in it (3.7 of
// the per-pixel background's CPU-s for 1500 x 512^2 on the dev VM). count[j]: the column's samples left in
// (its median undefined when 0).
__attribute__((target("avx2"))) void lowerMedians16Avx2(const float* buf, std::size_t nf, int w, int xa,
                                                        std::vector<std::int32_t>& keys, float* median,
                                                        std::size_t* count) {
  keys.resize(nf * 16);
  const __m256i kMagnitude = _mm256_set1_epi32(0x7FFFFFFF);
  __m256i lo[2], hi[2], cnt[2];
  for (int q = 0; q < 2; ++q) {
    lo[q] = _mm256_set1_epi32(std::numeric_limits<std::int32_t>::max());  // the smallest key, so far
    hi[q] = _mm256_set1_epi32(std::numeric_limits<std::int32_t>::min());  // the largest finite key
    cnt[q] = _mm256_setzero_si256();
  }
  for (std::size_t n = 0; n < nf; ++n)
    for (int q = 0; q < 2; ++q) {
      const __m256 v = _mm256_loadu_ps(buf + n * w + xa + 8 * q);
      const __m256i bits = _mm256_castps_si256(v);
      __m256i key = _mm256_xor_si256(bits, _mm256_and_si256(_mm256_srai_epi32(bits, 31), kMagnitude));
      const __m256i nan = _mm256_castps_si256(_mm256_cmp_ps(v, v, _CMP_UNORD_Q));
      key = _mm256_blendv_epi8(key, kMagnitude, nan);  // NaN: INT_MAX, above every float's key
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(keys.data() + n * 16 + 8 * q), key);
      lo[q] = _mm256_min_epi32(lo[q], key);
      hi[q] = _mm256_blendv_epi8(_mm256_max_epi32(hi[q], key), hi[q], nan);
      cnt[q] = _mm256_sub_epi32(cnt[q], _mm256_andnot_si256(nan, _mm256_set1_epi32(-1)));
    }
  // Smallest key K with #(keys <= K) >= r + 1, r = (c - 1) / 2: lo <= K <= hi throughout.
  __m256i need[2];
  for (int q = 0; q < 2; ++q) {
    const __m256i c = cnt[q];
    need[q] = _mm256_add_epi32(_mm256_srli_epi32(_mm256_sub_epi32(c, _mm256_set1_epi32(1)), 1),
                               _mm256_set1_epi32(1));
    lo[q] = _mm256_min_epi32(lo[q], hi[q]);  // a column without samples: lo = hi, nothing to find
  }
  const __m256i nfv = _mm256_set1_epi32(static_cast<std::int32_t>(nf));
  for (;;) {
    const __m256i open0 = _mm256_cmpgt_epi32(hi[0], lo[0]), open1 = _mm256_cmpgt_epi32(hi[1], lo[1]);
    if (_mm256_testz_si256(_mm256_or_si256(open0, open1), _mm256_set1_epi32(-1))) break;
    __m256i mid[2], above[2];
    for (int q = 0; q < 2; ++q) {
      // lo + (hi - lo) / 2 in unsigned 32-bit arithmetic (the difference may exceed INT_MAX).
      mid[q] = _mm256_add_epi32(lo[q], _mm256_srli_epi32(_mm256_sub_epi32(hi[q], lo[q]), 1));
      above[q] = _mm256_setzero_si256();
    }
    const std::int32_t* k = keys.data();
    for (std::size_t n = 0; n < nf; ++n, k += 16) {
      above[0] = _mm256_sub_epi32(
          above[0], _mm256_cmpgt_epi32(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(k)), mid[0]));
      above[1] = _mm256_sub_epi32(
          above[1], _mm256_cmpgt_epi32(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(k + 8)), mid[1]));
    }
    for (int q = 0; q < 2; ++q) {
      const __m256i atOrBelow = _mm256_sub_epi32(nfv, above[q]);
      // enough at or below mid: hi = mid, else lo = mid + 1 (only where the lane is still open).
      const __m256i enough = _mm256_cmpgt_epi32(atOrBelow, _mm256_sub_epi32(need[q], _mm256_set1_epi32(1)));
      const __m256i open = q == 0 ? open0 : open1;
      hi[q] = _mm256_blendv_epi8(hi[q], mid[q], _mm256_and_si256(open, enough));
      lo[q] = _mm256_blendv_epi8(lo[q], _mm256_add_epi32(mid[q], _mm256_set1_epi32(1)),
                                 _mm256_andnot_si256(enough, open));
    }
  }
  alignas(32) std::int32_t out[16], c[16];
  for (int q = 0; q < 2; ++q) {
    const __m256i key = lo[q];
    const __m256i bits = _mm256_xor_si256(key, _mm256_and_si256(_mm256_srai_epi32(key, 31), kMagnitude));
    _mm256_store_si256(reinterpret_cast<__m256i*>(out + 8 * q), bits);
    _mm256_store_si256(reinterpret_cast<__m256i*>(c + 8 * q), cnt[q]);
  }
  for (int j = 0; j < 16; ++j) {
    std::memcpy(median + j, out + j, sizeof(float));
    count[j] = static_cast<std::size_t>(c[j]);
  }
}
#endif

}  // namespace

void cutStrongAboveMedian(float* buf, std::size_t nf, int w, double offset, std::vector<float>& col,
                          bool allowSimd) {
#ifdef ST_STRONG_CUT_AVX2
  if (allowSimd && haveAvx2() && nf < (std::size_t(1) << 30)) {
    const float kNaN = std::numeric_limits<float>::quiet_NaN();
    constexpr int kBlock = 16;
    thread_local std::vector<std::int32_t> keys;
    for (int xa = 0; xa + kBlock <= w; xa += kBlock) {
      float median[kBlock], cut[kBlock];
      std::size_t c[kBlock];
      lowerMedians16Avx2(buf, nf, w, xa, keys, median, c);
      for (int j = 0; j < kBlock; ++j)
        cut[j] = c[j] == 0 ? std::numeric_limits<float>::infinity()
                           : floatAtOrBelow(static_cast<double>(median[j]) + offset);
      for (std::size_t n = 0; n < nf; ++n) {
        float* row = buf + n * w + xa;
        for (int j = 0; j < kBlock; ++j)
          if (row[j] > cut[j]) row[j] = kNaN;
      }
    }
    const int done = w / kBlock * kBlock;
    if (done == w) return;
    // The last columns (fewer than 16) below, as without AVX2.
    cutStrongAboveMedianFrom(buf, nf, w, done, offset, col);
    return;
  }
#else
  (void)allowSimd;
#endif
  cutStrongAboveMedianFrom(buf, nf, w, 0, offset, col);
}

}  // namespace st::stats

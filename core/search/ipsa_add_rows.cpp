// The inner loop of the exact search: a few contiguous frame rows added into one accumulator row, the
// accumulator kept in registers. AVX2 is chosen at run time so the library still runs on older x86-64.
#include <cstddef>

#include "ipsa_kernel.hpp"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#define ST_IPSA_HAVE_AVX2_PATH 1
#endif

namespace st::search::detail {

namespace {

void addRowsScalar(float* acc, const float* const* src, int count, int wp) {
  for (int k = 0; k < count; ++k) {
    const float* s = src[k];
    for (int x = 0; x < wp; ++x)
      acc[x] += s[x];
  }
}

#ifdef ST_IPSA_HAVE_AVX2_PATH
__attribute__((target("avx2"))) void addRowsAvx2(float* acc, const float* const* src, int count, int wp) {
  int x = 0;
  for (; x + 64 <= wp; x += 64) {
    __m256 a0 = _mm256_loadu_ps(acc + x);
    __m256 a1 = _mm256_loadu_ps(acc + x + 8);
    __m256 a2 = _mm256_loadu_ps(acc + x + 16);
    __m256 a3 = _mm256_loadu_ps(acc + x + 24);
    __m256 a4 = _mm256_loadu_ps(acc + x + 32);
    __m256 a5 = _mm256_loadu_ps(acc + x + 40);
    __m256 a6 = _mm256_loadu_ps(acc + x + 48);
    __m256 a7 = _mm256_loadu_ps(acc + x + 56);
    for (int k = 0; k < count; ++k) {
      const float* s = src[k] + x;
      a0 = _mm256_add_ps(a0, _mm256_loadu_ps(s));
      a1 = _mm256_add_ps(a1, _mm256_loadu_ps(s + 8));
      a2 = _mm256_add_ps(a2, _mm256_loadu_ps(s + 16));
      a3 = _mm256_add_ps(a3, _mm256_loadu_ps(s + 24));
      a4 = _mm256_add_ps(a4, _mm256_loadu_ps(s + 32));
      a5 = _mm256_add_ps(a5, _mm256_loadu_ps(s + 40));
      a6 = _mm256_add_ps(a6, _mm256_loadu_ps(s + 48));
      a7 = _mm256_add_ps(a7, _mm256_loadu_ps(s + 56));
    }
    _mm256_storeu_ps(acc + x, a0);
    _mm256_storeu_ps(acc + x + 8, a1);
    _mm256_storeu_ps(acc + x + 16, a2);
    _mm256_storeu_ps(acc + x + 24, a3);
    _mm256_storeu_ps(acc + x + 32, a4);
    _mm256_storeu_ps(acc + x + 40, a5);
    _mm256_storeu_ps(acc + x + 48, a6);
    _mm256_storeu_ps(acc + x + 56, a7);
  }
  for (; x + 8 <= wp; x += 8) {
    __m256 a = _mm256_loadu_ps(acc + x);
    for (int k = 0; k < count; ++k)
      a = _mm256_add_ps(a, _mm256_loadu_ps(src[k] + x));
    _mm256_storeu_ps(acc + x, a);
  }
  for (; x < wp; ++x) {
    for (int k = 0; k < count; ++k)
      acc[x] += src[k][x];
  }
}

__attribute__((target("avx2"))) float maxOfAvx2(const float* a, int n) {
  int i = 0;
  float m = a[0];
  if (n >= 16) {
    __m256 m0 = _mm256_loadu_ps(a);
    __m256 m1 = _mm256_loadu_ps(a + 8);
    for (i = 16; i + 16 <= n; i += 16) {
      m0 = _mm256_max_ps(m0, _mm256_loadu_ps(a + i));
      m1 = _mm256_max_ps(m1, _mm256_loadu_ps(a + i + 8));
    }
    alignas(32) float lanes[8];
    _mm256_store_ps(lanes, _mm256_max_ps(m0, m1));
    for (const float l : lanes)
      m = l > m ? l : m;
  }
  for (; i < n; ++i)
    m = a[i] > m ? a[i] : m;
  return m;
}

bool cpuHasAvx2() {
  static const bool has = __builtin_cpu_supports("avx2") != 0;
  return has;
}
#endif

}  // namespace

float maxOf(const float* a, int n) {
#ifdef ST_IPSA_HAVE_AVX2_PATH
  if (cpuHasAvx2()) return maxOfAvx2(a, n);
#endif
  float m = a[0];
  for (int i = 1; i < n; ++i)
    m = a[i] > m ? a[i] : m;
  return m;
}

void addRows(float* acc, const float* const* src, int count, int wp) {
#ifdef ST_IPSA_HAVE_AVX2_PATH
  if (cpuHasAvx2()) {
    addRowsAvx2(acc, src, count, wp);
    return;
  }
#endif
  addRowsScalar(acc, src, count, wp);
}

}  // namespace st::search::detail

#include "moffat_samples.hpp"

#include <bit>
#include <cmath>
#include <cstdint>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#define ST_MOFFAT_LANES_AVX2 1
#endif

#include "st/common/env_flag.hpp"

namespace st::psf::detail {
namespace {

// fdlibm's constants (e_exp.c, e_log.c), as their bit patterns.
constexpr double kLn2Hi = 0x1.62e42fee00000p-1;  // ln 2's high part: k * kLn2Hi is exact for |k| < 2^20
constexpr double kLn2Lo = 0x1.a39ef35793c76p-33;
constexpr double kInvLn2 = 0x1.71547652b82fep+0;
constexpr double kP1 = 0x1.555555555553ep-3, kP2 = -0x1.6c16c16bebd93p-9, kP3 = 0x1.1566aaf25de2cp-14,
                 kP4 = -0x1.bbd41c5d26bf1p-20, kP5 = 0x1.6376972bea4d0p-25;
constexpr double kLg1 = 0x1.5555555555593p-1, kLg2 = 0x1.999999997fa04p-2, kLg3 = 0x1.2492494229359p-2,
                 kLg4 = 0x1.c71c51d8e78afp-3, kLg5 = 0x1.7466496cb03dep-3, kLg6 = 0x1.39a09d078c69fp-3,
                 kLg7 = 0x1.2f112df3e5244p-3;
constexpr double kSqrt2 = 0x1.6a09e667f3bcdp+0;
constexpr double kExpLimit = 700.0;  // |x| below it: 2^k stays a normal number
constexpr double kMinNormal = 0x1p-1022;
constexpr std::uint64_t kMantissa = (std::uint64_t{1} << 52) - 1;
constexpr std::uint64_t kOneBits = std::uint64_t{1023} << 52;

}  // namespace

// x = k ln2 + r, |r| <= ln2 / 2 (k by rounding to nearest, ties to even), r in two parts (hi - lo); exp(r)
// by fdlibm's rational form 1 + 2r / (R(r^2) - r), then scaled by 2^k from its exponent bits.
double laneExp(double x) {
  if (!(x > -kExpLimit && x < kExpLimit)) return std::exp(x);
  const double k = std::nearbyint(x * kInvLn2);
  const double hi = x - k * kLn2Hi;
  const double lo = k * kLn2Lo;
  const double r = hi - lo;
  const double t = r * r;
  const double c = r - t * (kP1 + t * (kP2 + t * (kP3 + t * (kP4 + t * kP5))));
  const double y = 1.0 - ((lo - (r * c) / (2.0 - c)) - hi);
  const auto e = static_cast<std::int64_t>(k);
  return y * std::bit_cast<double>(static_cast<std::uint64_t>(e + 1023) << 52);
}

// x = 2^e m, m in [sqrt(2)/2, sqrt(2)); log m = 2 atanh(s), s = f / (2 + f), f = m - 1, by fdlibm's
// polynomial in s^2; then e ln2 added in two parts.
double laneLog(double x) {
  if (!(x >= kMinNormal && x < HUGE_VAL)) return std::log(x);
  const auto bits = std::bit_cast<std::uint64_t>(x);
  double e = static_cast<double>(static_cast<std::int64_t>(bits >> 52) - 1023);
  double m = std::bit_cast<double>((bits & kMantissa) | kOneBits);
  if (m > kSqrt2) {
    m *= 0.5;
    e += 1.0;
  }
  const double f = m - 1.0;
  const double s = f / (2.0 + f);
  const double z = s * s;
  const double w = z * z;
  const double t1 = w * (kLg2 + w * (kLg4 + w * kLg6));
  const double t2 = z * (kLg1 + w * (kLg3 + w * (kLg5 + w * kLg7)));
  const double r = t2 + t1;
  const double hfsq = 0.5 * f * f;
  return e * kLn2Hi - ((hfsq - (s * (hfsq + r) + e * kLn2Lo)) - f);
}

#ifdef ST_MOFFAT_LANES_AVX2
namespace {

// `out` with the lanes where `ok` is clear taken from `library` of `x` (the inputs the scalar functions hand
// to the C library).
template <class Library>
__attribute__((target("avx2"))) inline __m256d fromLibrary(__m256d x, __m256d out, __m256d ok,
                                                           Library library) {
  const int good = _mm256_movemask_pd(ok);
  if (good == 0xF) return out;
  alignas(32) double in[4], res[4];
  _mm256_store_pd(in, x);
  _mm256_store_pd(res, out);
  for (int l = 0; l < 4; ++l)
    if (!(good & (1 << l))) res[l] = library(in[l]);
  return _mm256_load_pd(res);
}

// laneExp and laneLog in four lanes, the same operations in the same order.
__attribute__((target("avx2"))) inline __m256d exp4(__m256d x) {
  const __m256d k = _mm256_round_pd(_mm256_mul_pd(x, _mm256_set1_pd(kInvLn2)),
                                    _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC);
  const __m256d hi = _mm256_sub_pd(x, _mm256_mul_pd(k, _mm256_set1_pd(kLn2Hi)));
  const __m256d lo = _mm256_mul_pd(k, _mm256_set1_pd(kLn2Lo));
  const __m256d r = _mm256_sub_pd(hi, lo);
  const __m256d t = _mm256_mul_pd(r, r);
  __m256d poly = _mm256_add_pd(_mm256_set1_pd(kP4), _mm256_mul_pd(t, _mm256_set1_pd(kP5)));
  poly = _mm256_add_pd(_mm256_set1_pd(kP3), _mm256_mul_pd(t, poly));
  poly = _mm256_add_pd(_mm256_set1_pd(kP2), _mm256_mul_pd(t, poly));
  poly = _mm256_add_pd(_mm256_set1_pd(kP1), _mm256_mul_pd(t, poly));
  const __m256d c = _mm256_sub_pd(r, _mm256_mul_pd(t, poly));
  const __m256d q = _mm256_div_pd(_mm256_mul_pd(r, c), _mm256_sub_pd(_mm256_set1_pd(2.0), c));
  const __m256d y = _mm256_sub_pd(_mm256_set1_pd(1.0), _mm256_sub_pd(_mm256_sub_pd(lo, q), hi));
  // k (an integer in a double) as int64 by the 1.5 * 2^52 trick, then 2^k from its exponent bits.
  const __m256d magic = _mm256_set1_pd(0x1.8p52);
  const __m256i ki =
      _mm256_sub_epi64(_mm256_castpd_si256(_mm256_add_pd(k, magic)), _mm256_castpd_si256(magic));
  const __m256i scale = _mm256_slli_epi64(_mm256_add_epi64(ki, _mm256_set1_epi64x(1023)), 52);
  const __m256d ok = _mm256_and_pd(_mm256_cmp_pd(x, _mm256_set1_pd(-kExpLimit), _CMP_GT_OQ),
                                   _mm256_cmp_pd(x, _mm256_set1_pd(kExpLimit), _CMP_LT_OQ));
  return fromLibrary(x, _mm256_mul_pd(y, _mm256_castsi256_pd(scale)), ok,
                     [](double v) { return std::exp(v); });
}

__attribute__((target("avx2"))) inline __m256d set(double v) {
  return _mm256_set1_pd(v);
}

__attribute__((target("avx2"))) inline __m256d log4(__m256d x) {
  const __m256i bits = _mm256_castpd_si256(x);
  const __m256d magic = _mm256_set1_pd(0x1.8p52);
  // The biased exponent (x > 0 where used) less 1023, as a double by the same trick.
  const __m256i ei = _mm256_sub_epi64(_mm256_srli_epi64(bits, 52), _mm256_set1_epi64x(1023));
  __m256d e = _mm256_sub_pd(_mm256_castsi256_pd(_mm256_add_epi64(ei, _mm256_castpd_si256(magic))), magic);
  __m256d m = _mm256_castsi256_pd(
      _mm256_or_si256(_mm256_and_si256(bits, _mm256_set1_epi64x(static_cast<long long>(kMantissa))),
                      _mm256_set1_epi64x(static_cast<long long>(kOneBits))));
  const __m256d big = _mm256_cmp_pd(m, _mm256_set1_pd(kSqrt2), _CMP_GT_OQ);
  m = _mm256_blendv_pd(m, _mm256_mul_pd(m, _mm256_set1_pd(0.5)), big);
  e = _mm256_blendv_pd(e, _mm256_add_pd(e, _mm256_set1_pd(1.0)), big);
  const __m256d f = _mm256_sub_pd(m, _mm256_set1_pd(1.0));
  const __m256d s = _mm256_div_pd(f, _mm256_add_pd(_mm256_set1_pd(2.0), f));
  const __m256d z = _mm256_mul_pd(s, s);
  const __m256d w = _mm256_mul_pd(z, z);
  const __m256d t1 = _mm256_mul_pd(
      w, _mm256_add_pd(set(kLg2), _mm256_mul_pd(w, _mm256_add_pd(set(kLg4), _mm256_mul_pd(w, set(kLg6))))));
  const __m256d t2 = _mm256_mul_pd(
      z, _mm256_add_pd(
             set(kLg1),
             _mm256_mul_pd(
                 w, _mm256_add_pd(set(kLg3),
                                  _mm256_mul_pd(w, _mm256_add_pd(set(kLg5), _mm256_mul_pd(w, set(kLg7))))))));
  const __m256d r = _mm256_add_pd(t2, t1);
  const __m256d hfsq = _mm256_mul_pd(_mm256_mul_pd(set(0.5), f), f);
  const __m256d inner =
      _mm256_add_pd(_mm256_mul_pd(s, _mm256_add_pd(hfsq, r)), _mm256_mul_pd(e, set(kLn2Lo)));
  const __m256d out =
      _mm256_sub_pd(_mm256_mul_pd(e, set(kLn2Hi)), _mm256_sub_pd(_mm256_sub_pd(hfsq, inner), f));
  const __m256d ok = _mm256_and_pd(_mm256_cmp_pd(x, set(kMinNormal), _CMP_GE_OQ),
                                   _mm256_cmp_pd(x, set(HUGE_VAL), _CMP_LT_OQ));
  return fromLibrary(x, out, ok, [](double v) { return std::log(v); });
}

__attribute__((target("avx2"))) void exp4To(const double* x, double* out) {
  _mm256_storeu_pd(out, exp4(_mm256_loadu_pd(x)));
}

__attribute__((target("avx2"))) void log4To(const double* x, double* out) {
  _mm256_storeu_pd(out, log4(_mm256_loadu_pd(x)));
}

// The five sums of moffatModelAt's lanes (value, d/dx0 and d/dy0 without the amplitude, q rr, lnu value).
__attribute__((target("avx2"))) void sumsAvx2(const double* p, double bx, double by, const MoffatSamples& s,
                                              double sums[5][4]) {
  const double r2inv = 1.0 / (p[kR] * p[kR]);
  const __m256d vbx = _mm256_set1_pd(bx), vby = _mm256_set1_pd(by), vr2 = _mm256_set1_pd(r2inv);
  const __m256d nb = _mm256_set1_pd(-p[kBeta]), tb = _mm256_set1_pd((2.0 * p[kBeta]) * r2inv);
  const __m256d one = _mm256_set1_pd(1.0);
  __m256d aP = _mm256_setzero_pd(), aX = aP, aY = aP, aR = aP, aB = aP;
  for (std::size_t k = 0; k < s.weight.size(); k += 4) {
    const __m256d dx = _mm256_add_pd(vbx, _mm256_loadu_pd(s.ox.data() + k));
    const __m256d dy = _mm256_add_pd(vby, _mm256_loadu_pd(s.oy.data() + k));
    const __m256d rr = _mm256_add_pd(_mm256_mul_pd(dx, dx), _mm256_mul_pd(dy, dy));
    const __m256d u = _mm256_add_pd(one, _mm256_mul_pd(rr, vr2));
    const __m256d lnu = log4(u);
    const __m256d val = _mm256_mul_pd(_mm256_loadu_pd(s.weight.data() + k), exp4(_mm256_mul_pd(nb, lnu)));
    const __m256d q = _mm256_div_pd(_mm256_mul_pd(val, tb), u);
    aP = _mm256_add_pd(aP, val);
    aX = _mm256_add_pd(aX, _mm256_mul_pd(q, dx));
    aY = _mm256_add_pd(aY, _mm256_mul_pd(q, dy));
    aR = _mm256_add_pd(aR, _mm256_mul_pd(q, rr));
    aB = _mm256_add_pd(aB, _mm256_mul_pd(lnu, val));
  }
  _mm256_storeu_pd(sums[0], aP);
  _mm256_storeu_pd(sums[1], aX);
  _mm256_storeu_pd(sums[2], aY);
  _mm256_storeu_pd(sums[3], aR);
  _mm256_storeu_pd(sums[4], aB);
}

}  // namespace
#endif

bool moffatLanesAvx2() {
#ifdef ST_MOFFAT_LANES_AVX2
  static const bool avx2 = __builtin_cpu_supports("avx2") != 0;
  return avx2;
#else
  return false;
#endif
}

void laneExp4(const double* x, double* out) {
#ifdef ST_MOFFAT_LANES_AVX2
  if (moffatLanesAvx2()) return exp4To(x, out);
#endif
  for (int l = 0; l < 4; ++l)
    out[l] = laneExp(x[l]);
}

void laneLog4(const double* x, double* out) {
#ifdef ST_MOFFAT_LANES_AVX2
  if (moffatLanesAvx2()) return log4To(x, out);
#endif
  for (int l = 0; l < 4; ++l)
    out[l] = laneLog(x[l]);
}

MoffatSamples moffatSamples(const Moffat::GaussRule& g, const SmearKernel& smear) {
  MoffatSamples s;
  for (std::size_t k = 0; k < smear.weight.size(); ++k)
    for (int j = 0; j < g.n; ++j)
      for (int i = 0; i < g.n; ++i) {
        s.ox.push_back(g.x[i] - smear.dx[k]);
        s.oy.push_back(g.x[j] - smear.dy[k]);
        s.weight.push_back(smear.weight[k] * g.w[i] * g.w[j]);
      }
  while (s.weight.size() % 4 != 0) {  // weight 0: each lane's sums gain +0.0 (exp and log stay finite)
    s.ox.push_back(0.0);
    s.oy.push_back(0.0);
    s.weight.push_back(0.0);
  }
  return s;
}

double moffatModelAt(const double* p, double px, double py, const MoffatSamples& s, double* grad) {
  return moffatModelAtLanes(p, px, py, s, grad, moffatLanesAvx2());
}

double moffatModelAtLanes(const double* p, double px, double py, const MoffatSamples& s, double* grad,
                          bool avx2) {
  const double bx = px - p[kX0], by = py - p[kY0];
  double sums[5][4] = {};
#ifdef ST_MOFFAT_LANES_AVX2
  if (avx2 && moffatLanesAvx2()) {
    sumsAvx2(p, bx, by, s, sums);
  } else
#endif
  {
    const double r2inv = 1.0 / (p[kR] * p[kR]);
    const double nb = -p[kBeta], tb = (2.0 * p[kBeta]) * r2inv;
    for (std::size_t k = 0; k < s.weight.size(); k += 4)
      for (std::size_t l = 0; l < 4; ++l) {
        const double dx = bx + s.ox[k + l], dy = by + s.oy[k + l];
        const double rr = dx * dx + dy * dy;
        const double u = 1.0 + rr * r2inv;
        const double lnu = laneLog(u);
        const double val = s.weight[k + l] * laneExp(nb * lnu);
        const double q = (val * tb) / u;
        sums[0][l] += val;
        sums[1][l] += q * dx;
        sums[2][l] += q * dy;
        sums[3][l] += q * rr;
        sums[4][l] += lnu * val;
      }
  }
  double total[5];
  for (int v = 0; v < 5; ++v)
    total[v] = (sums[v][0] + sums[v][1]) + (sums[v][2] + sums[v][3]);
  if (grad) {
    grad[kX0] = p[kAmp] * total[1];
    grad[kY0] = p[kAmp] * total[2];
    grad[kR] = p[kAmp] * (total[3] / p[kR]);
    grad[kBeta] = -(p[kAmp] * total[4]);
    grad[kAmp] = total[0];
    grad[kBg] = 1.0;
  }
  return p[kBg] + p[kAmp] * total[0];
}

double moffatModelAtLibm(const double* p, double px, double py, const Moffat::GaussRule& g,
                         const SmearKernel& smear, double* grad) {
  const double r2inv = 1.0 / (p[kR] * p[kR]);
  double sumP = 0.0, sumDx = 0.0, sumDy = 0.0, sumDr = 0.0, sumDb = 0.0;
  for (std::size_t k = 0; k < smear.weight.size(); ++k) {
    for (int j = 0; j < g.n; ++j) {
      const double dy = py + g.x[j] - p[kY0] - smear.dy[k];
      for (int i = 0; i < g.n; ++i) {
        const double dx = px + g.x[i] - p[kX0] - smear.dx[k];
        const double wt = smear.weight[k] * g.w[i] * g.w[j];
        const double rr = dx * dx + dy * dy;
        const double u = 1.0 + rr * r2inv;
        const double lnu = std::log(u);
        const double val = wt * std::exp(-p[kBeta] * lnu);
        const double q = 2.0 * p[kBeta] * val / u * r2inv;  // 2 beta u^(-beta-1) / R^2
        sumP += val;
        sumDx += q * dx;
        sumDy += q * dy;
        sumDr += q * rr / p[kR];
        sumDb -= lnu * val;
      }
    }
  }
  if (grad) {
    grad[kX0] = p[kAmp] * sumDx;
    grad[kY0] = p[kAmp] * sumDy;
    grad[kR] = p[kAmp] * sumDr;
    grad[kBeta] = p[kAmp] * sumDb;
    grad[kAmp] = sumP;
    grad[kBg] = 1.0;
  }
  return p[kBg] + p[kAmp] * sumP;
}

namespace {
std::atomic<int> g_libmScopes{0};
}  // namespace

LibmModelScope::LibmModelScope() {
  g_libmScopes.fetch_add(1);
}

LibmModelScope::~LibmModelScope() {
  g_libmScopes.fetch_sub(1);
}

bool moffatModelLibm() {
  static const bool libm = envFlag("ST_PSF_LIBM_MODEL");
  return libm || g_libmScopes.load(std::memory_order_relaxed) > 0;
}

}  // namespace st::psf::detail

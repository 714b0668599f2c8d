#include "st/stats/noise_model.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#endif

#include "st/common/error.hpp"
#include "st/common/parallel.hpp"
#include "st/stats/background.hpp"
#include "st/stats/sep_background.hpp"

namespace st::stats {
namespace {

constexpr double kChi2OneMedian = 0.454936423119572;  // median of chi^2 with one degree of freedom

double medianOf(std::vector<double>& v) {
  if (v.empty()) return 0.0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

/// Sums of d = x - centre and d^2 over the values with |d| <= limit, and their count, each sum kept in 8
/// partial sums (value i in lane i % 8, the lanes added in order at the end) so that the additions do not
/// wait on each other (a sequential sum is bound by the add latency: 4 cycles a value); the same lanes on
/// every CPU, so the result does not depend on the AVX2 path (it differs from one sequential sum only in
/// the last bits of a double).
void clippedSumsScalar(const float* v, std::size_t n, std::size_t i0, double centre, double limit, double* s,
                       double* ss, std::size_t* c) {
  for (std::size_t i = i0; i < n; ++i) {
    const double d = v[i] - centre;
    const bool in = std::fabs(d) <= limit;
    const double dd = in ? d : 0.0;
    s[i % 8] += dd;
    ss[i % 8] += dd * dd;
    c[i % 8] += in;
  }
}

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define ST_NOISE_MODEL_AVX2 1
__attribute__((target("avx2"))) std::size_t clippedSumsAvx2(const float* v, std::size_t n, double centre,
                                                            double limit, double* s, double* ss,
                                                            std::size_t* c) {
  const __m256d ctr = _mm256_set1_pd(centre), lim = _mm256_set1_pd(limit);
  const __m256d absMask = _mm256_castsi256_pd(_mm256_set1_epi64x(0x7fffffffffffffffLL));
  __m256d s0 = _mm256_setzero_pd(), s1 = s0, q0 = s0, q1 = s0;
  __m256i c0 = _mm256_setzero_si256(), c1 = c0;
  std::size_t i = 0;
  for (; i + 8 <= n; i += 8) {
    const __m256 x = _mm256_loadu_ps(v + i);
    const __m256d d0 = _mm256_sub_pd(_mm256_cvtps_pd(_mm256_castps256_ps128(x)), ctr);
    const __m256d d1 = _mm256_sub_pd(_mm256_cvtps_pd(_mm256_extractf128_ps(x, 1)), ctr);
    const __m256d in0 = _mm256_cmp_pd(_mm256_and_pd(d0, absMask), lim, _CMP_LE_OQ);
    const __m256d in1 = _mm256_cmp_pd(_mm256_and_pd(d1, absMask), lim, _CMP_LE_OQ);
    const __m256d e0 = _mm256_and_pd(d0, in0), e1 = _mm256_and_pd(d1, in1);
    s0 = _mm256_add_pd(s0, e0);
    s1 = _mm256_add_pd(s1, e1);
    q0 = _mm256_add_pd(q0, _mm256_mul_pd(e0, e0));
    q1 = _mm256_add_pd(q1, _mm256_mul_pd(e1, e1));
    c0 = _mm256_sub_epi64(c0, _mm256_castpd_si256(in0));
    c1 = _mm256_sub_epi64(c1, _mm256_castpd_si256(in1));
  }
  _mm256_storeu_pd(s, s0);
  _mm256_storeu_pd(s + 4, s1);
  _mm256_storeu_pd(ss, q0);
  _mm256_storeu_pd(ss + 4, q1);
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(c), c0);
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(c + 4), c1);
  return i;
}
#endif

void clippedSums(const float* v, std::size_t n, double centre, double limit, double& sOut, double& ssOut,
                 std::size_t& cOut) {
  double s[8] = {}, ss[8] = {};
  std::size_t c[8] = {};
  std::size_t i0 = 0;
#ifdef ST_NOISE_MODEL_AVX2
  static const bool avx2 = __builtin_cpu_supports("avx2") != 0;
  if (avx2) i0 = clippedSumsAvx2(v, n, centre, limit, s, ss, c);
#endif
  clippedSumsScalar(v, n, i0, centre, limit, s, ss, c);
  sOut = 0.0;
  ssOut = 0.0;
  cOut = 0;
  for (int j = 0; j < 8; ++j) {
    sOut += s[j];
    ssOut += ss[j];
    cOut += c[j];
  }
}

/// The k-th smallest of the finite values v (the value nth_element leaves at v[k]; v may be reordered):
/// two values of an evenly spaced sample of 64 bracket rank k, one branch-free pass counts the values below
/// the bracket and gathers those inside it, and nth_element runs on those only (about a fifth); when rank k
/// falls outside the bracket, nth_element on all of v.
template <class T>
T kthSmallest(std::vector<T>& v, std::size_t k, std::vector<T>& bracket) {
  const std::size_t n = v.size();
  if (n >= 256) {
    constexpr int m = 64;
    T sample[m];
    for (int i = 0; i < m; ++i)
      sample[i] = v[(2 * static_cast<std::size_t>(i) + 1) * n / (2 * m)];
    std::sort(sample, sample + m);
    const int at = static_cast<int>(static_cast<double>(k) * m / static_cast<double>(n));
    const T lo = sample[std::max(0, at - 6)], hi = sample[std::min(m - 1, at + 6)];
    bracket.resize(n);
    std::size_t below = 0, inside = 0;
    for (const T x : v) {
      bracket[inside] = x;
      inside += (x >= lo) & (x <= hi);
      below += x < lo;
    }
    if (below <= k && k < below + inside) {
      const auto kth = bracket.begin() + static_cast<std::ptrdiff_t>(k - below);
      std::nth_element(bracket.begin(), kth, bracket.begin() + static_cast<std::ptrdiff_t>(inside));
      return *kth;
    }
  }
  const auto kth = v.begin() + static_cast<std::ptrdiff_t>(k);
  std::nth_element(v.begin(), kth, v.end());
  return *kth;
}

/// Mean of `v` clipped at +-k sigma about itself, started from the median and 1.4826 MAD of every s-th
/// value (s = size / 1024, at least 1: the start only sets the first clip's bounds, which the iterations
/// then refine on every value); NaN when fewer than `minCount` values. Up to 5 clip iterations; it stops
/// once an iteration keeps as many values as the one before (the same set, so the centre and sigma no
/// longer change: the ones after would repeat it). `start` is scratch space.
double clippedMean(const float* v, std::size_t n, double k, std::size_t minCount, std::vector<float>& start,
                   std::vector<float>& bracket) {
  if (n < minCount) return std::nan("");
  const std::size_t stride = std::max<std::size_t>(1, n / 1024);
  start.clear();
  for (std::size_t i = 0; i < n; i += stride)
    start.push_back(v[i]);
  double centre = kthSmallest(start, start.size() / 2, bracket);
  for (float& x : start)
    x = std::fabs(x - static_cast<float>(centre));
  double sigma = 1.4826 * kthSmallest(start, start.size() / 2, bracket);
  if (!(sigma > 0.0)) return centre;
  std::size_t previous = 0;
  for (int it = 0; it < 5; ++it) {
    double s = 0.0, ss = 0.0;
    std::size_t c = 0;
    clippedSums(v, n, centre, k * sigma, s, ss, c);
    if (c < minCount) break;
    const double m = s / static_cast<double>(c);
    centre += m;
    sigma = std::sqrt(std::max(0.0, ss / static_cast<double>(c) - m * m));
    if (!(sigma > 0.0) || c == previous) break;
    previous = c;
  }
  return centre;
}

/// Whether every value of p[0, n) is non-zero and finite (tested on the bits, so the loop vectorises).
bool allSet(const float* p, int n) {
  std::uint32_t bad = 0;
  for (int i = 0; i < n; ++i) {
    std::uint32_t u;
    std::memcpy(&u, p + i, sizeof u);
    bad |= static_cast<std::uint32_t>((u & 0x7fffffffu) == 0u) | static_cast<std::uint32_t>((u & 0x7f800000u) == 0x7f800000u);
  }
  return bad == 0;
}

/// Where column x falls between the mesh's cell centres: cells i0, i1 and the weight f of i1.
struct ColumnWeight {
  int i0 = 0, i1 = 0;
  double f = 0.0;
};

// row -= corr where row is non-zero and finite (zeroed and masked samples stay 0): v - 0 is v, also for
// -0, infinities and NaN, so the AVX2 path subtracts everywhere with corr zeroed where not set.
void subtractWhereSetScalar(float* row, const float* corr, int x0, int w) {
  for (int x = x0; x < w; ++x)
    if (row[x] != 0.0f && std::isfinite(row[x])) row[x] -= corr[x];
}

#ifdef ST_NOISE_MODEL_AVX2
__attribute__((target("avx2"))) void subtractWhereSetAvx2(float* row, const float* corr, int w) {
  const __m256 zero = _mm256_setzero_ps(), kMax = _mm256_set1_ps(std::numeric_limits<float>::max());
  const __m256 absMask = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
  int x = 0;
  for (; x + 8 <= w; x += 8) {
    const __m256 v = _mm256_loadu_ps(row + x);
    const __m256 set = _mm256_and_ps(_mm256_cmp_ps(v, zero, _CMP_NEQ_UQ),
                                     _mm256_cmp_ps(_mm256_and_ps(v, absMask), kMax, _CMP_LE_OQ));
    _mm256_storeu_ps(row + x, _mm256_sub_ps(v, _mm256_and_ps(_mm256_loadu_ps(corr + x), set)));
  }
  subtractWhereSetScalar(row, corr, x, w);
}
#endif

void subtractWhereSet(float* row, const float* corr, int w) {
#ifdef ST_NOISE_MODEL_AVX2
  static const bool avx2 = __builtin_cpu_supports("avx2") != 0;
  if (avx2) return subtractWhereSetAvx2(row, corr, w);
#endif
  subtractWhereSetScalar(row, corr, 0, w);
}

}  // namespace

FrameBackgrounds removeFrameBackgrounds(FrameCube& cube, const FrameBackgroundParams& params,
                                        ProgressSink& progress, CancelToken& cancel) {
  FrameBackgrounds out;
  const std::size_t nf = cube.frameCount(), np = cube.framePixels();
  out.level.assign(nf, std::nan(""));
  out.rms.assign(nf, std::nan(""));
  if (!params.enabled || nf == 0) return out;
  // SEP's sep_background and sep_bkg_subarray, pixel for pixel (st/stats/sep_background.hpp: libsep's
  // backguess walked its histogram on every clip iteration, half of this stage's time).
  const sep::MeshGrid grid = sep::meshGrid(cube.width(), cube.height(), params.meshPx);
  const int filter = std::max(1, params.filterCells);
  const bool hasMask = cube.mask().size() == cube.pixels().size();
  std::vector<sep::FrameModel> models(nf);
  std::atomic<std::size_t> done{0};
  progress.report(0.0, "frame backgrounds");
  parallelFor(nf, 1, [&](std::size_t b, std::size_t e) {
    for (std::size_t n = b; n < e; ++n) {
      cancel.throwIfCancelled();
      models[n] = sep::model(cube.frame(n), hasMask ? cube.mask().data() + n * np : nullptr, grid, filter);
      out.level[n] = models[n].global;
      out.rms[n] = models[n].globalrms;
      const std::size_t d = ++done;
      if (d % 32 == 0) progress.report(0.5 * double(d) / double(nf), "frame backgrounds");
    }
  });
  std::vector<double> levels;
  for (double l : out.level)
    if (std::isfinite(l)) levels.push_back(l);
  out.restoredLevel = medianOf(levels);
  const float restored = static_cast<float>(out.restoredLevel);
  const std::vector<sep::SplineRow> rows = sep::rowTable(grid.height, grid.bh, grid.ny);
  const std::vector<sep::SplineColumn> cols = sep::columnTable(grid.width, grid.bw, grid.nx);
  done = 0;
  parallelFor(nf, 1, [&](std::size_t b, std::size_t e) {
    for (std::size_t n = b; n < e; ++n) {
      cancel.throwIfCancelled();
      sep::subtract(cube.frame(n), grid, models[n], rows, cols, restored);
      models[n] = sep::FrameModel{};
      const std::size_t d = ++done;
      if (d % 32 == 0) progress.report(0.5 + 0.5 * double(d) / double(nf), "frame backgrounds");
    }
  });
  out.framesSkipped = nf - levels.size();
  progress.report(1.0, "frame backgrounds");
  return out;
}

double removeResidualMeans(FrameCube& cube, int meshPx, double clipSigma, ProgressSink& progress,
                           CancelToken& cancel) {
  const int w = cube.width(), h = cube.height();
  const int mesh = std::max(8, meshPx);
  const int nx = (w + mesh - 1) / mesh, ny = (h + mesh - 1) / mesh;
  const std::size_t nf = cube.frameCount();
  std::vector<double> sumSq(nf, 0.0);
  std::vector<std::size_t> cells(nf, 0);
  std::vector<ColumnWeight> columns(static_cast<std::size_t>(w));
  for (int x = 0; x < w; ++x) {
    const double u = std::clamp((x + 0.5) / mesh - 0.5, 0.0, static_cast<double>(nx - 1));
    columns[x].i0 = static_cast<int>(u);
    columns[x].i1 = std::min(columns[x].i0 + 1, nx - 1);
    columns[x].f = u - columns[x].i0;
  }
  std::atomic<std::size_t> done{0};
  parallelFor(nf, 1, [&](std::size_t b, std::size_t e) {
    std::vector<float> values(static_cast<std::size_t>(mesh) * mesh), scratch, bracket;
    std::vector<double> means(static_cast<std::size_t>(nx) * ny);
    std::vector<float> corr(static_cast<std::size_t>(w));
    for (std::size_t n = b; n < e; ++n) {
      cancel.throwIfCancelled();
      float* f = cube.frame(n);
      std::vector<double> good;
      for (int j = 0; j < ny; ++j)
        for (int i = 0; i < nx; ++i) {
          // The cell's non-zero finite values, in row order (branch-free: each written, kept or overwritten).
          const int xa = i * mesh, xb = std::min(w, (i + 1) * mesh);
          std::size_t kept = 0;
          for (int y = j * mesh; y < std::min(h, (j + 1) * mesh); ++y) {
            const float* row = f + static_cast<std::size_t>(y) * w;
            if (allSet(row + xa, xb - xa)) {  // the usual case: the whole segment, copied
              std::memcpy(values.data() + kept, row + xa, sizeof(float) * static_cast<std::size_t>(xb - xa));
              kept += static_cast<std::size_t>(xb - xa);
              continue;
            }
            for (int x = xa; x < xb; ++x) {
              const float v = row[x];
              values[kept] = v;
              kept += (v != 0.0f) & (std::fabs(v) <= std::numeric_limits<float>::max());
            }
          }
          const double m = clippedMean(values.data(), kept, clipSigma,
                                       std::max<std::size_t>(32, static_cast<std::size_t>(mesh) * mesh / 16), scratch,
                                       bracket);
          means[static_cast<std::size_t>(j) * nx + i] = m;
          if (std::isfinite(m)) good.push_back(m);
        }
      if (good.empty()) continue;  // a fully zeroed frame
      const double fill = medianOf(good);
      for (double& m : means) {
        if (!std::isfinite(m)) m = fill;
        sumSq[n] += m * m;
        ++cells[n];
      }
      // Bilinear between cell centres, separably: the mesh row interpolated at y, then along x by tables.
      std::vector<double> rowMesh(static_cast<std::size_t>(nx));
      for (int y = 0; y < h; ++y) {
        const double wy = std::clamp((y + 0.5) / mesh - 0.5, 0.0, static_cast<double>(ny - 1));
        const int j0 = static_cast<int>(wy), j1 = std::min(j0 + 1, ny - 1);
        const double fy = wy - j0;
        for (int i = 0; i < nx; ++i)
          rowMesh[i] = means[static_cast<std::size_t>(j0) * nx + i] * (1.0 - fy) +
                       means[static_cast<std::size_t>(j1) * nx + i] * fy;
        for (int x = 0; x < w; ++x) {
          const ColumnWeight& c = columns[x];
          corr[x] = static_cast<float>(rowMesh[c.i0] * (1.0 - c.f) + rowMesh[c.i1] * c.f);
        }
        subtractWhereSet(f + static_cast<std::size_t>(y) * w, corr.data(), w);
      }
      const std::size_t d = ++done;
      if (d % 32 == 0) progress.report(double(d) / double(nf), "residual means");
    }
  });
  double s = 0.0;
  std::size_t c = 0;
  for (std::size_t n = 0; n < nf; ++n) {
    s += sumSq[n];
    c += cells[n];
  }
  progress.report(1.0, "residual means");
  return c > 0 ? std::sqrt(s / static_cast<double>(c)) : 0.0;
}

NoiseModel NoiseModel::uniform(int width, int height, std::size_t frames, double sigma) {
  NoiseModel m;
  m.variance = Image(width, height, static_cast<float>(sigma * sigma));
  m.frameScale.assign(frames, 1.0);
  m.sigmaRef = sigma;
  return m;
}

NoiseModel estimateNoiseModel(const FrameCube& zeroBiased, const Image& pixelSigma,
                              const std::vector<std::uint8_t>& unmeasured, const NoiseModelParams& params,
                              CancelToken& cancel) {
  const int w = zeroBiased.width(), h = zeroBiased.height();
  if (pixelSigma.width != w || pixelSigma.height != h)
    throw InputError("noise model: per-pixel sigma of " + std::to_string(pixelSigma.width) + "x" +
                     std::to_string(pixelSigma.height) + " does not match frames of " + std::to_string(w) +
                     "x" + std::to_string(h));
  const std::size_t np = zeroBiased.framePixels(), nf = zeroBiased.frameCount();
  Image raw(w, h);
  std::vector<std::uint8_t> valid(np, 0);
  for (std::size_t i = 0; i < np; ++i) {
    const float s = pixelSigma.pixels[i];
    const bool ok = (unmeasured.empty() || !unmeasured[i]) && s > 0.0f && std::isfinite(s);
    valid[i] = ok;
    raw.pixels[i] = ok ? s * s : 0.0f;
  }
  if (std::count(valid.begin(), valid.end(), 1) == 0)
    throw InputError("noise model: no pixel has a measured frame-to-frame sigma");
  // Smooth in two passes: the second leaves out pixels above twice the first (the frame-to-frame scatter of
  // pixels that a mover or a star's residual crosses holds their signal, not noise).
  const Image first = boxSmooth(raw, params.smoothBoxPx, valid);
  std::vector<std::uint8_t> quiet = valid;
  for (std::size_t i = 0; i < np; ++i)
    if (quiet[i] && raw.pixels[i] > 2.0f * first.pixels[i]) quiet[i] = 0;
  const Image smooth = boxSmooth(raw, params.smoothBoxPx, quiet);
  // Holes wider than the box (a mover's whole track left out of the background, a masked star) take the
  // median variance of the measured pixels: a weight of 0 there would throw away what crosses them.
  std::vector<double> measured;
  measured.reserve(np / 8 + 1);
  for (std::size_t i = 0; i < np; i += 8)
    if (valid[i]) measured.push_back(raw.pixels[i]);
  if (measured.empty())
    for (std::size_t i = 0; i < np; ++i)
      if (valid[i]) measured.push_back(raw.pixels[i]);
  const float fill = static_cast<float>(medianOf(measured));
  NoiseModel m;
  m.variance = Image(w, h);
  std::vector<double> vs;
  vs.reserve(np / 4);
  for (std::size_t i = 0; i < np; ++i) {
    const float s = smooth.pixels[i] > 0.0f  ? smooth.pixels[i]
                    : first.pixels[i] > 0.0f ? first.pixels[i]
                                             : fill;
    const bool noisy = params.noisyPixelRatio > 0.0 && valid[i] && raw.pixels[i] > params.noisyPixelRatio * s;
    const float v = noisy ? raw.pixels[i] : s;
    m.variance.pixels[i] = v > 0.0f && std::isfinite(v) ? v : 0.0f;
    if (m.variance.pixels[i] > 0.0f && (i % 4 == 0)) vs.push_back(m.variance.pixels[i]);
  }
  m.frameScale.assign(nf, std::nan(""));
  const int stride = std::max(1, params.sampleStride);
  parallelFor(nf, 4, [&](std::size_t b, std::size_t e) {
    std::vector<double> r, bracket;
    for (std::size_t n = b; n < e; ++n) {
      cancel.throwIfCancelled();
      const float* f = zeroBiased.frame(n);
      r.clear();
      for (std::size_t i = n % stride; i < np; i += stride) {
        const float v = m.variance.pixels[i];
        if (f[i] != 0.0f && v > 0.0f && std::isfinite(f[i])) r.push_back(double(f[i]) * f[i] / v);
      }
      if (r.size() >= 100) m.frameScale[n] = std::sqrt(kthSmallest(r, r.size() / 2, bracket) / kChi2OneMedian);
    }
  });
  std::vector<double> scales;
  for (double s : m.frameScale)
    if (std::isfinite(s) && s > 0.0) scales.push_back(s);
  const double typical = scales.empty() ? 1.0 : medianOf(scales);
  for (double& s : m.frameScale)
    if (!(std::isfinite(s) && s > 0.0)) s = typical;
  m.sigmaRef = std::sqrt(medianOf(vs)) * typical;
  return m;
}

}  // namespace st::stats

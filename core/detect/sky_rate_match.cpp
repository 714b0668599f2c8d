#include "sky_rate_match.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#if defined(__x86_64__)
#include <immintrin.h>
#endif

#include <opencv2/imgproc.hpp>

#include "st/common/fftw_plans.hpp"
#include "st/common/parallel.hpp"

namespace st::detect::detail {

double minPeakCompressed() {
  return std::log1p(4.0);
}

std::vector<Source> sourcesOf(const cv::Mat& image, double minPeak) {
  constexpr int kMinSourcePixels = 4;
  CV_Assert(image.type() == CV_64FC1);
  const int w = image.cols, h = image.rows;
  // The positive pixels in row order, 8-connected by union-find (each set's root its first pixel): the
  // images are mostly zeros (a few hundred stars' cores), so this touches them once instead of labelling
  // every pixel (cv::connectedComponents and a scan of its labels: half the paired stars' time, issue 16).
  struct Pixel {
    int x, y;
    double v;
  };
  thread_local std::vector<Pixel> px;
  thread_local std::vector<std::size_t> parent;
  thread_local std::vector<std::ptrdiff_t> above, here;  // the pixel index at each column of the rows, or -1
  px.clear();
  parent.clear();
  above.assign(static_cast<std::size_t>(w) + 2, -1);
  here.assign(static_cast<std::size_t>(w) + 2, -1);
  auto root = [&](std::size_t k) {
    while (parent[k] != k)
      k = parent[k] = parent[parent[k]];
    return k;
  };
  auto unite = [&](std::size_t a, std::ptrdiff_t b) {
    if (b < 0) return;
    const std::size_t ra = root(a), rb = root(static_cast<std::size_t>(b));
    if (ra < rb) parent[rb] = ra;
    if (rb < ra) parent[ra] = rb;
  };
  std::size_t rowStart = 0, aboveStart = 0;  // the first pixels of this row and of the row above
  for (int y = 0; y < h; ++y) {
    const double* row = image.ptr<double>(y);
    for (int x = 0; x < w; ++x) {
      if (x + 8 <= w) {  // runs of zeros (most of the image) eight at a time
        bool any = false;
        for (int i = 0; i < 8; ++i)
          any |= row[x + i] > 0.0;
        if (!any) {
          x += 7;
          continue;
        }
      }
      if (!(row[x] > 0.0)) continue;
      const std::size_t k = px.size();
      px.push_back({x, y, row[x]});
      parent.push_back(k);
      here[static_cast<std::size_t>(x) + 1] = static_cast<std::ptrdiff_t>(k);
      unite(k, here[static_cast<std::size_t>(x)]);  // west
      for (int dx = 0; dx < 3; ++dx)                // north-west, north, north-east
        unite(k, above[static_cast<std::size_t>(x) + dx]);
    }
    // The row above is cleared where it was set, and becomes the next row's.
    for (std::size_t k = aboveStart; k < rowStart; ++k)
      above[static_cast<std::size_t>(px[k].x) + 1] = -1;
    std::swap(above, here);
    aboveStart = rowStart;
    rowStart = px.size();
  }
  // The components in cv::connectedComponents' label order (its default 8-way algorithm labels 2 x 2 blocks
  // in row order: a component's label is that of its first block), so that everything summed over them
  // later is summed in the same order (tests/core/test_sky_rate_phase_shift.cpp holds OpenCV to it).
  struct Component {
    long long block = 0;  // the first 2 x 2 block's row-major index
    Source acc;
    double sw = 0.0;
    int pixels = 0;
  };
  std::vector<std::size_t> slot(px.size(), 0);
  std::vector<Component> comps;
  const long long blocksPerRow = (w + 1) / 2;
  for (std::size_t k = 0; k < px.size(); ++k) {
    const std::size_t r = root(k);
    const long long block = static_cast<long long>(px[k].y / 2) * blocksPerRow + px[k].x / 2;
    if (r == k) {
      slot[k] = comps.size();
      comps.push_back({block, {}, 0.0, 0});
    } else {
      slot[k] = slot[r];
      comps[slot[k]].block = std::min(comps[slot[k]].block, block);
    }
    // Each component's sums in row order, as the label scan made them.
    Component& c = comps[slot[k]];
    const double v = px[k].v;
    c.acc.x += v * px[k].x, c.acc.y += v * px[k].y, c.acc.peak = std::max(c.acc.peak, v);
    c.sw += v;
    ++c.pixels;
  }
  std::stable_sort(comps.begin(), comps.end(),
                   [](const Component& a, const Component& b) { return a.block < b.block; });
  std::vector<Source> out;
  for (const Component& c : comps)
    if (c.pixels >= kMinSourcePixels && c.acc.peak >= minPeak && c.sw > 0)
      out.push_back({c.acc.x / c.sw, c.acc.y / c.sw, c.acc.peak});
  return out;
}

std::vector<SourcePair> pairSources(const cv::Mat& a, const cv::Mat& b, cv::Point2d coarse, double minPeak) {
  constexpr double kMatchRadiusPx = 3.0;
  const std::vector<Source> sa = sourcesOf(a, minPeak), sb = sourcesOf(b, minPeak);
  std::vector<SourcePair> out;
  for (const Source& s : sa) {
    const Source* best = nullptr;
    double bestD = kMatchRadiusPx;
    for (const Source& t : sb) {
      const double dist = std::hypot(t.x - s.x - coarse.x, t.y - s.y - coarse.y);
      if (dist < bestD) bestD = dist, best = &t;
    }
    if (best) out.push_back({s, *best});
  }
  return out;
}

bool consensusOffset(const cv::Mat& a, const cv::Mat& b, cv::Point2d coarse, double minPeak, cv::Point2d* d) {
  const std::vector<SourcePair> p = pairSources(a, b, coarse, minPeak);
  if (p.size() < 3) return false;
  std::vector<double> dx, dy;
  for (const SourcePair& q : p)
    dx.push_back(q.b.x - q.a.x), dy.push_back(q.b.y - q.a.y);
  std::nth_element(dx.begin(), dx.begin() + dx.size() / 2, dx.end());
  std::nth_element(dy.begin(), dy.begin() + dy.size() / 2, dy.end());
  *d = {dx[dx.size() / 2], dy[dy.size() / 2]};
  return true;
}

namespace {

struct Centroid {
  double x = 0.0, y = 0.0, varX = 0.0, varY = 0.0;
};

// SExtractor's windowed centroid: x <- x + 2 sum(w I (x_i - x)) / sum(w I) with a Gaussian window w of
// sigma `sw` about x, over the valid pixels. False when less than kMinWindowValid of the window's weight
// is valid, when the windowed flux is not positive, or when the centroid wanders off (to a neighbour).
// Invalid pixels bias the centroid; the two images of an offset share one validity mask, so the bias is
// common to both and drops out of their difference.
bool windowedCentroid(const LinearImage& im, double x0, double y0, double sw, Centroid* c) {
  constexpr double kMinWindowValid = 0.7;
  const int r = static_cast<int>(std::ceil(3.0 * sw)) + 1;
  double x = x0, y = y0;
  for (int it = 0; it < 16; ++it) {
    const int cx = static_cast<int>(std::lround(x)), cy = static_cast<int>(std::lround(y));
    double sum = 0.0, sx = 0.0, sy = 0.0, vx = 0.0, vy = 0.0, wAll = 0.0, wValid = 0.0;
    for (int j = cy - r; j <= cy + r; ++j) {
      const bool rowIn = j >= 0 && j < im.value.rows;
      for (int i = cx - r; i <= cx + r; ++i) {
        const double dx = i - x, dy = j - y;
        const double w = std::exp(-(dx * dx + dy * dy) / (2.0 * sw * sw));
        wAll += w;
        if (!rowIn || i < 0 || i >= im.value.cols || !im.valid.at<unsigned char>(j, i)) continue;
        const double v = im.value.at<float>(j, i), n = im.noise.at<float>(j, i);
        wValid += w;
        sum += w * v, sx += w * v * dx, sy += w * v * dy;
        vx += w * w * dx * dx * n * n, vy += w * w * dy * dy * n * n;
      }
    }
    if (!(sum > 0.0) || wValid < kMinWindowValid * wAll) return false;
    const double stepX = 2.0 * sx / sum, stepY = 2.0 * sy / sum;
    x += stepX, y += stepY;
    if (std::hypot(x - x0, y - y0) > 2.0 * sw) return false;
    c->varX = 4.0 * vx / (sum * sum), c->varY = 4.0 * vy / (sum * sum);
    if (std::fabs(stepX) < 1e-4 && std::fabs(stepY) < 1e-4) break;
  }
  c->x = x, c->y = y;
  return true;
}

// The window of a source: the sigma of its light in `im` about (x, y) within 2.5 px, clamped to [1, 4] px
// (a pixel-sampled PSF of FWHM 2.4 .. 9.4 px).
double windowSigma(const LinearImage& im, double x, double y) {
  const int cx = static_cast<int>(std::lround(x)), cy = static_cast<int>(std::lround(y));
  double sum = 0.0, m2 = 0.0;
  for (int j = std::max(0, cy - 3); j <= std::min(im.value.rows - 1, cy + 3); ++j)
    for (int i = std::max(0, cx - 3); i <= std::min(im.value.cols - 1, cx + 3); ++i) {
      const double d2 = (i - x) * (i - x) + (j - y) * (j - y);
      const double v = im.value.at<float>(j, i);
      if (d2 > 2.5 * 2.5 || v <= 0.0) continue;
      sum += v, m2 += v * d2;
    }
  return sum > 0.0 ? std::clamp(std::sqrt(m2 / sum / 2.0), 1.0, 4.0) : 1.5;
}

// True for a saturated (flat-topped) source near (x, y): its brightest pixel stands less above the mean of
// its 8 neighbours than 0.2 times their height above the mean of the next ring (a PSF of any width drops
// at least ~0.4 times as much in the first ring as in the second), at a peak of >= 20 sigma. Saturated
// stars are left out of the offsets: their cores are clipped at a level that varies with the flat and
// the vignetting as they drift, and their bleed with their flux, moving their centroids by ~0.1 px.
bool flatTopped(const LinearImage& im, double x, double y) {
  const int cx = static_cast<int>(std::lround(x)), cy = static_cast<int>(std::lround(y));
  if (cx < 3 || cy < 3 || cx >= im.value.cols - 3 || cy >= im.value.rows - 3) return false;
  int px = cx, py = cy;  // the brightest pixel next to the centroid
  for (int j = cy - 1; j <= cy + 1; ++j)
    for (int i = cx - 1; i <= cx + 1; ++i)
      if (im.value.at<float>(j, i) > im.value.at<float>(py, px)) px = i, py = j;
  const double peak = im.value.at<float>(py, px);
  if (!(peak > 20.0 * im.noise.at<float>(py, px))) return false;
  double ring1 = 0.0, ring2 = 0.0;
  int n1 = 0, n2 = 0;
  for (int j = -2; j <= 2; ++j)
    for (int i = -2; i <= 2; ++i) {
      const int r = std::max(std::abs(i), std::abs(j));
      if (r == 0) continue;
      const double v = im.value.at<float>(py + j, px + i);
      if (r == 1) ring1 += v, ++n1;
      if (r == 2) ring2 += v, ++n2;
    }
  ring1 /= n1, ring2 /= n2;
  return peak - ring1 < 0.2 * (ring1 - ring2);
}

}  // namespace

bool windowedOffset(const LinearImage& a, const LinearImage& b, const std::vector<SourcePair>& pairs,
                    cv::Point2d* d, cv::Point2d* var) {
  struct Estimate {
    double dx, dy, vx, vy;
  };
  // Each pair's estimate on every core (the windowed centroids' Gaussian weights dominate: ~110 ms a link
  // of 1432 x 1370 Lowell frames on one thread, and that sequence has 3 links), kept in the pairs' order.
  std::vector<Estimate> each(pairs.size());
  std::vector<char> made(pairs.size(), 0);
  parallelFor(pairs.size(), 4, [&](std::size_t k0, std::size_t k1) {
    for (std::size_t k = k0; k < k1; ++k) {
      const SourcePair& p = pairs[k];
      if (flatTopped(a, p.a.x, p.a.y) || flatTopped(b, p.b.x, p.b.y)) continue;
      const double sw = windowSigma(a, p.a.x, p.a.y);
      Centroid ca, cb;
      if (!windowedCentroid(a, p.a.x, p.a.y, sw, &ca) || !windowedCentroid(b, p.b.x, p.b.y, sw, &cb))
        continue;
      each[k] = {cb.x - ca.x, cb.y - ca.y, ca.varX + cb.varX, ca.varY + cb.varY};
      made[k] = 1;
    }
  });
  std::vector<Estimate> e;
  for (std::size_t k = 0; k < pairs.size(); ++k)
    if (made[k]) e.push_back(each[k]);
  if (e.size() < 2) return false;
  auto median = [](std::vector<double> v) {
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  };
  std::vector<double> ex, ey;
  for (const Estimate& q : e)
    ex.push_back(q.dx), ey.push_back(q.dy);
  const double mx = median(ex), my = median(ey);
  constexpr double kFloorPx = 0.03;
  double sx = 0.0, sy = 0.0, wx = 0.0, wy = 0.0;
  int n = 0;
  for (const Estimate& q : e) {
    if (std::fabs(q.dx - mx) > 3.0 * std::sqrt(q.vx) + 0.1 ||
        std::fabs(q.dy - my) > 3.0 * std::sqrt(q.vy) + 0.1)
      continue;
    const double ux = 1.0 / (q.vx + kFloorPx * kFloorPx), uy = 1.0 / (q.vy + kFloorPx * kFloorPx);
    sx += ux * q.dx, wx += ux, sy += uy * q.dy, wy += uy;
    ++n;
  }
  if (n < 2) return false;
  *d = {sx / wx, sy / wy};
  *var = {1.0 / wx, 1.0 / wy};
  return true;
}

namespace {

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define ST_SKY_RATE_MATCH_AVX2 1
// normaliseCrossPower's complexes [0, 4k): the scalar loop's double operations in its order, four at a
// time (no fused multiply-adds, IEEE division and square root: the same floats).
__attribute__((target("avx2"))) std::size_t normaliseCrossPowerAvx2(float* fa, const float* fb,
                                                                    std::size_t n) {
  const __m256d zero = _mm256_setzero_pd();
  std::size_t i = 0;
  for (; i + 4 <= n; i += 4) {
    // [re0 im0 re1 im1] and [re2 im2 re3 im3] of each spectrum, widened.
    const __m256d a0 = _mm256_cvtps_pd(_mm_loadu_ps(fa + 2 * i)),
                  a1 = _mm256_cvtps_pd(_mm_loadu_ps(fa + 2 * i + 4));
    const __m256d b0 = _mm256_cvtps_pd(_mm_loadu_ps(fb + 2 * i)),
                  b1 = _mm256_cvtps_pd(_mm_loadu_ps(fb + 2 * i + 4));
    // re = ar br + ai bi: the pairwise sums of a b; im = ai br - ar bi: the pairwise differences of
    // swap(a) b. Lanes come out as complexes [0 2 1 3].
    const __m256d re = _mm256_hadd_pd(_mm256_mul_pd(a0, b0), _mm256_mul_pd(a1, b1));
    const __m256d im = _mm256_hsub_pd(_mm256_mul_pd(_mm256_permute_pd(a0, 0x5), b0),
                                      _mm256_mul_pd(_mm256_permute_pd(a1, 0x5), b1));
    const __m256d m = _mm256_sqrt_pd(_mm256_add_pd(_mm256_mul_pd(re, re), _mm256_mul_pd(im, im)));
    const __m256d ok = _mm256_cmp_pd(m, zero, _CMP_GT_OQ);
    const __m256d nr = _mm256_and_pd(_mm256_div_pd(re, m), ok), ni = _mm256_and_pd(_mm256_div_pd(im, m), ok);
    // Back to [re0 im0 re1 im1] and [re2 im2 re3 im3]: of the lanes' [0 2 | 1 3], unpacklo takes [0 | 1]
    // and unpackhi [2 | 3].
    _mm_storeu_ps(fa + 2 * i, _mm256_cvtpd_ps(_mm256_unpacklo_pd(nr, ni)));
    _mm_storeu_ps(fa + 2 * i + 4, _mm256_cvtpd_ps(_mm256_unpackhi_pd(nr, ni)));
  }
  return i;
}
#endif

// The first index of the largest value of c[0, n) (finite values), or n when any value is not finite.
__attribute__((target_clones("avx2", "default"))) float largestFinite(const float* c, std::size_t n,
                                                                      bool* finite) {
  float best = -std::numeric_limits<float>::infinity();
  bool ok = true;
  for (std::size_t i = 0; i < n; ++i) {
    ok &= std::isfinite(c[i]);
    best = c[i] > best ? c[i] : best;
  }
  *finite = ok;
  return best;
}

}  // namespace

void normaliseCrossPower(fftwf_complex* fa, const fftwf_complex* fb, std::size_t n, bool vectorised) {
  std::size_t i0 = 0;
#ifdef ST_SKY_RATE_MATCH_AVX2
  static const bool avx2 = __builtin_cpu_supports("avx2") != 0;
  if (vectorised && avx2) i0 = normaliseCrossPowerAvx2(&fa[0][0], &fb[0][0], n);
#else
  (void)vectorised;
#endif
  for (std::size_t i = i0; i < n; ++i) {
    const double re = static_cast<double>(fa[i][0]) * fb[i][0] + static_cast<double>(fa[i][1]) * fb[i][1];
    const double im = static_cast<double>(fa[i][1]) * fb[i][0] - static_cast<double>(fa[i][0]) * fb[i][1];
    const double m = std::sqrt(re * re + im * im);  // OpenCV's magnitude (std::hypot: 2.6% of the CPU time)
    fa[i][0] = m > 0.0 ? static_cast<float>(re / m) : 0.0f;
    fa[i][1] = m > 0.0 ? static_cast<float>(im / m) : 0.0f;
  }
}

std::size_t firstLargestShifted(const float* c, int nx, int ny) {
  const std::size_t nr = static_cast<std::size_t>(nx) * ny;
  const int xMid = nx / 2, yMid = ny / 2;
  auto shiftedIndex = [&](std::size_t i) {
    const int x = static_cast<int>(i % static_cast<std::size_t>(nx)), y = static_cast<int>(i / nx);
    return static_cast<std::size_t>((y + yMid) % ny) * nx + static_cast<std::size_t>((x + xMid) % nx);
  };
  bool finite = false;
  const float top = largestFinite(c, nr, &finite);
  if (finite) {
    // Of the values equal to the largest, the first in the shifted row order.
    std::size_t best = nr;
    for (std::size_t i = 0; i < nr; ++i)
      if (c[i] == top) best = std::min(best, shiftedIndex(i));
    return best;
  }
  // NaN or infinite values: the row-order scan's own choice, as it always made it.
  std::size_t bestAt = 0, bestShifted = shiftedIndex(0);
  for (std::size_t i = 1; i < nr; ++i) {
    if (c[i] < c[bestAt]) continue;
    if (c[i] > c[bestAt] || shiftedIndex(i) < bestShifted) bestAt = i, bestShifted = shiftedIndex(i);
  }
  return bestShifted;
}

void windowedFloats(const cv::Mat& image, const cv::Mat& window, float* out, std::size_t stride) {
  for (int y = 0; y < image.rows; ++y) {
    const double* row = image.ptr<double>(y);
    const double* win = window.empty() ? nullptr : window.ptr<double>(y);
    float* dst = out + static_cast<std::size_t>(y) * stride;
    if (win)
      for (int x = 0; x < image.cols; ++x)
        dst[x] = static_cast<float>(win[x] * row[x]);
    else
      for (int x = 0; x < image.cols; ++x)
        dst[x] = static_cast<float>(row[x]);
  }
}

cv::Point2d phaseShift(const cv::Mat& a, const cv::Mat& b, const cv::Mat& window, double* response) {
  CV_Assert(a.type() == CV_64FC1 && b.type() == CV_64FC1 && a.size() == b.size());
  CV_Assert(window.empty() || (window.type() == CV_64FC1 && window.size() == a.size()));
  // OpenCV's padding: zeros to its optimal DFT size, the window applied before (it is padded with zeros).
  const int w = a.cols, h = a.rows;
  const int nx = cv::getOptimalDFTSize(w), ny = cv::getOptimalDFTSize(h);
  const std::size_t nr = static_cast<std::size_t>(nx) * ny, nc = static_cast<std::size_t>(nx / 2 + 1) * ny;
  const fftw::PlanPair plans = fftw::plans2d(nx, ny, false);
  // Each thread's buffers, kept between calls (the chain's links run ~100 of these on every core: fresh
  // buffers were page faults and zeroing).
  struct Buffers {
    std::size_t nr = 0, nc = 0;
    fftw::RealBuf in;
    fftw::CplxBuf fa, fb;
  };
  thread_local Buffers buf;
  if (buf.nr != nr || buf.nc != nc) {
    buf.in = fftw::allocReal(nr, "sky rate");
    buf.fa = fftw::allocCplx(nc, "sky rate");
    buf.fb = fftw::allocCplx(nc, "sky rate");
    buf.nr = nr, buf.nc = nc;
  }
  float* in = buf.in.get();
  auto transform = [&](const cv::Mat& m, fftwf_complex* out) {
    if (nx != w || ny != h) std::fill(in, in + nr, 0.0f);  // the padding
    windowedFloats(m, window, in, static_cast<std::size_t>(nx));
    fftwf_execute_dft_r2c(plans.forward, in, out);
  };
  transform(a, buf.fa.get());
  transform(b, buf.fb.get());
  // The normalised cross-power spectrum A conj(B) / |A conj(B)| (0 where it vanishes), transformed back
  // without scaling: a peak of up to nx * ny at the offset.
  normaliseCrossPower(buf.fa.get(), buf.fb.get(), nc);
  fftwf_execute_dft_c2r(plans.inverse, buf.fa.get(), in);
  // OpenCV's quadrant swap (numpy's fftshift: shifted x is x - nx / 2 modulo nx), its first maximum in row
  // order and the centroid of the 5 x 5 px around it (cut at the edges): the offset from the centre, and
  // the summed peak / (nx * ny) as the response.
  const int xFrom = nx - nx / 2, yFrom = ny - ny / 2;
  auto at = [&](int x, int y) {
    const int sx = (x + xFrom) % nx, sy = (y + yFrom) % ny;
    return static_cast<double>(in[static_cast<std::size_t>(sy) * nx + sx]);
  };
  const std::size_t bestShifted = firstLargestShifted(in, nx, ny);
  const int px = static_cast<int>(bestShifted % static_cast<std::size_t>(nx));
  const int py = static_cast<int>(bestShifted / static_cast<std::size_t>(nx));
  double sx = 0.0, sy = 0.0, sum = 0.0;
  for (int y = std::max(0, py - 2); y <= std::min(ny - 1, py + 2); ++y)
    for (int x = std::max(0, px - 2); x <= std::min(nx - 1, px + 2); ++x) {
      const double v = at(x, y);
      sx += x * v, sy += y * v, sum += v;
    }
  if (response) *response = sum / static_cast<double>(nr);
  sum += 2.220446049250313e-16;  // OpenCV's DBL_EPSILON against a zero sum
  return {0.5 * nx - sx / sum, 0.5 * ny - sy / sum};
}

}  // namespace st::detect::detail

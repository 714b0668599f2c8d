#include "st/detect/registration.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <numeric>
#include <optional>
#include <sstream>
#include <utility>

#include "st/common/fftw_plans.hpp"
#include "st/common/parallel.hpp"

namespace st::detect {
namespace {

constexpr float kClipSigma = 30.0f;  ///< a star image's pixels are clipped here (bright stars do not dominate)
constexpr float kFloorSigma = 2.5f;  ///< and zeroed below this (the noise does not correlate)
constexpr int kBinAbove = 1024;      ///< frames wider or taller than this are binned 2x2 first
constexpr int kQuickFrames = 64;     ///< links sampled on long sequences before measuring every frame
constexpr int kMaxBack = 3;          ///< a failed link is retried against up to this many earlier frames
constexpr int kTaperPx = 24;         ///< star images fade to 0 over this band at the edges (at most 1/8 side)
constexpr double kHighPassPx = 12.0; ///< structure wider than this (a saturated star's clipped disk) is
                                     ///< filtered out of the correlation: point-like stars set the peak

using fftw::CplxBuf;
using fftw::RealBuf;

/// What depends only on the (binned) image size, made once per registration rather than per frame or link.
/// Edge taper (cosine over the outer band): a star entering or leaving the frame is cut by the edge, and the
/// cut is fixed on the detector; untapered, a bright star's cut pulls the correlation peak towards zero
/// shift (a drifting EMCCD field measured 0.2 px steps for 1 px ones while a 10.5 mag star entered).
/// High-pass on the r2c half spectrum (h rows of w / 2 + 1): 1 - exp(-(k s)^2 / 2), s = kHighPassPx /
/// (2 pi), so broad clipped disks of saturated stars do not dominate and blur the peak.
struct CorrelationWeights {
  std::vector<float> taperX, taperY;  ///< per column / row of the star image
  std::vector<float> highPass;        ///< per frequency of the half spectrum
};

CorrelationWeights correlationWeights(int w, int h) {
  CorrelationWeights cw;
  const int band = std::max(2, std::min(kTaperPx, std::min(w, h) / 8));
  const auto taper = [band](int n) {
    std::vector<float> t(static_cast<std::size_t>(n), 1.0f);
    for (int i = 0; i < n; ++i) {
      const int d = std::min(i, n - 1 - i);
      if (d < band)
        t[static_cast<std::size_t>(i)] =
            static_cast<float>(0.5 - 0.5 * std::cos(M_PI * (d + 0.5) / static_cast<double>(band)));
    }
    return t;
  };
  cw.taperX = taper(w);
  cw.taperY = taper(h);
  const int hw = w / 2 + 1;
  const double sx = 2.0 * M_PI / w, sy = 2.0 * M_PI / h, scale2 = kHighPassPx * kHighPassPx / (4.0 * M_PI * M_PI);
  cw.highPass.resize(static_cast<std::size_t>(hw) * h);
  for (int ky = 0; ky < h; ++ky) {
    const int fy = ky <= h / 2 ? ky : ky - h;
    const double ky2 = (sy * fy) * (sy * fy);
    for (int kx = 0; kx < hw; ++kx) {
      const double k2 = ky2 + (sx * kx) * (sx * kx);
      cw.highPass[static_cast<std::size_t>(ky) * hw + kx] = static_cast<float>(1.0 - std::exp(-0.5 * k2 * scale2));
    }
  }
  return cw;
}

/// The star image of one frame (model in the header), binned by `bin`, into `out` (w/bin x h/bin), tapered
/// at the edges with `weights` (made for w/bin x h/bin).
void starImage(const float* f, const std::uint8_t* mask, int w, int h, int bin, const CorrelationWeights& weights,
               float* out) {
  const int bw = w / bin, bh = h / bin;
  std::vector<float> sample;
  sample.reserve(static_cast<std::size_t>(w) * h / 7 + 1);
  for (std::size_t i = 0; i < static_cast<std::size_t>(w) * h; i += 7) {
    if ((mask && mask[i]) || !std::isfinite(f[i])) continue;
    sample.push_back(f[i]);
  }
  float med = 0.0f, sigma = 1.0f;
  if (sample.size() > 10) {
    auto mid = sample.begin() + static_cast<std::ptrdiff_t>(sample.size() / 2);
    std::nth_element(sample.begin(), mid, sample.end());
    med = *mid;
    for (float& v : sample)
      v = std::abs(v - med);
    std::nth_element(sample.begin(), mid, sample.end());
    sigma = std::max(1.4826f * *mid, 1e-12f);
  }
  // Binned: the sum of the bin's pixels, in the binned image's own sigma (sigma x bin).
  const float scale = 1.0f / (sigma * static_cast<float>(bin));
  for (int by = 0; by < bh; ++by) {
    for (int bx = 0; bx < bw; ++bx) {
      float s = 0.0f;
      for (int j = 0; j < bin; ++j) {
        const std::size_t row = static_cast<std::size_t>(by * bin + j) * w;
        for (int i = 0; i < bin; ++i) {
          const std::size_t k = row + static_cast<std::size_t>(bx * bin + i);
          if ((mask && mask[k]) || !std::isfinite(f[k])) continue;
          s += f[k] - med;
        }
      }
      float v = s * scale;
      v = v < kFloorSigma ? 0.0f : std::min(v, kClipSigma);
      out[static_cast<std::size_t>(by) * bw + bx] = v;
    }
  }
  for (int by = 0; by < bh; ++by) {
    const float wy = weights.taperY[static_cast<std::size_t>(by)];
    for (int bx = 0; bx < bw; ++bx)
      out[static_cast<std::size_t>(by) * bw + bx] *= wy * weights.taperX[static_cast<std::size_t>(bx)];
  }
}

/// Cross-correlation peak of two star images (w x h), high-pass filtered with `weights`: the step from b
/// to a, and its significance. `guide`: when set, the peak is taken within `guideRadius` (binned px,
/// circular distance) of this step (the chained estimate), so that a second peak elsewhere (a static
/// pattern) cannot be taken; the significance is still over the whole surface. `atGuideEdge` says when that
/// peak lies on the disk's rim (the slope of a peak outside it).
PixelOffset correlate(const float* a, const float* b, int w, int h, const CorrelationWeights& weights,
                      double& snr, const std::optional<PixelOffset>& guide = std::nullopt,
                      double guideRadius = 0.0, bool* atGuideEdge = nullptr) {
  const fftw::PlanPair plans = fftw::plans2d(w, h, false);
  const std::size_t nr = static_cast<std::size_t>(w) * h, nc = static_cast<std::size_t>(w / 2 + 1) * h;
  RealBuf in = fftw::allocReal(nr, "registration");
  CplxBuf fa = fftw::allocCplx(nc, "registration");
  CplxBuf fb = fftw::allocCplx(nc, "registration");
  std::memcpy(in.get(), a, sizeof(float) * nr);
  fftwf_execute_dft_r2c(plans.forward, in.get(), fa.get());
  std::memcpy(in.get(), b, sizeof(float) * nr);
  fftwf_execute_dft_r2c(plans.forward, in.get(), fb.get());
  for (std::size_t i = 0; i < nc; ++i) {  // A conj(B): c(s) = sum_x a(x + s) b(x), high-passed
    const float g = weights.highPass[i];
    const float re = fa[i][0] * fb[i][0] + fa[i][1] * fb[i][1];
    const float im = fa[i][1] * fb[i][0] - fa[i][0] * fb[i][1];
    fa[i][0] = g * re;
    fa[i][1] = g * im;
  }
  fftwf_execute_dft_c2r(plans.inverse, fa.get(), in.get());
  const float* c = in.get();
  double sum = 0.0, sum2 = 0.0;
  for (std::size_t i = 0; i < nr; ++i) {
    sum += c[i];
    sum2 += static_cast<double>(c[i]) * c[i];
  }
  std::size_t best = 0;
  if (guide) {  // the box around the guide (wrapped), pixels within the radius
    const auto wrap = [](int v, int n) { return ((v % n) + n) % n; };
    const int r = static_cast<int>(std::ceil(guideRadius));
    const int gx = static_cast<int>(std::lround(guide->x)), gy = static_cast<int>(std::lround(guide->y));
    bool any = false;
    double bestD = 0.0;
    for (int y = gy - r; y <= gy + r; ++y) {
      for (int x = gx - r; x <= gx + r; ++x) {
        const double d = std::hypot(x - guide->x, y - guide->y);
        if (d > guideRadius) continue;
        const std::size_t i = static_cast<std::size_t>(wrap(y, h)) * w + wrap(x, w);
        if (!any || c[i] > c[best]) best = i, bestD = d;
        any = true;
      }
    }
    if (atGuideEdge) *atGuideEdge = bestD > guideRadius - 1.0;
  } else {
    for (std::size_t i = 1; i < nr; ++i)
      if (c[i] > c[best]) best = i;
  }
  const double mean = sum / static_cast<double>(nr);
  const double rms = std::sqrt(std::max(0.0, sum2 / static_cast<double>(nr) - mean * mean));
  snr = rms > 0.0 ? (c[best] - mean) / rms : 0.0;
  const int px = static_cast<int>(best % static_cast<std::size_t>(w));
  const int py = static_cast<int>(best / static_cast<std::size_t>(w));
  const auto at = [&](int x, int y) {
    x = (x + w) % w;
    y = (y + h) % h;
    return static_cast<double>(c[static_cast<std::size_t>(y) * w + x]);
  };
  const auto vertex = [](double m, double z, double p) {
    const double d = m - 2.0 * z + p;
    return d < 0.0 ? std::clamp(0.5 * (m - p) / d, -0.5, 0.5) : 0.0;
  };
  double dx = px + vertex(at(px - 1, py), at(px, py), at(px + 1, py));
  double dy = py + vertex(at(px, py - 1), at(px, py), at(px, py + 1));
  if (dx >= 0.5 * w) dx -= w;  // circular: shifts in [-w/2, w/2)
  if (dy >= 0.5 * h) dy -= h;
  return {dx, dy};
}

/// Star images of the frames, computed on demand and kept (a link needs its two frames' images).
class StarImages {
 public:
  StarImages(const FrameCube& cube) : m_cube(cube) {
    m_bin = std::max(cube.width(), cube.height()) > kBinAbove ? 2 : 1;
    m_w = cube.width() / m_bin;
    m_h = cube.height() / m_bin;
    m_weights = correlationWeights(m_w, m_h);
  }
  [[nodiscard]] const CorrelationWeights& weights() const noexcept { return m_weights; }
  [[nodiscard]] int bin() const noexcept { return m_bin; }
  [[nodiscard]] int width() const noexcept { return m_w; }
  [[nodiscard]] int height() const noexcept { return m_h; }
  [[nodiscard]] std::vector<float> make(std::size_t n) const {
    std::vector<float> out(static_cast<std::size_t>(m_w) * m_h);
    const auto& mask = m_cube.mask();
    starImage(m_cube.frame(n), mask.empty() ? nullptr : mask.data() + n * m_cube.framePixels(), m_cube.width(),
              m_cube.height(), m_bin, m_weights, out.data());
    return out;
  }

 private:
  const FrameCube& m_cube;
  int m_bin = 1, m_w = 0, m_h = 0;
  CorrelationWeights m_weights;
};

/// The 1-sigma error (px, per axis) of a correlation step measured at peak significance `snr`: 1.5 px / SNR
/// (the scatter of links at SNR 80 on the paper's EMCCD cube: 0.016-0.02 px), inflated below SNR ~15, where
/// the peak is broad and may blend with noise peaks (links at SNR 8-12 scatter by 0.3-0.7 px there).
double linkSigmaPx(double snr) {
  const double s = std::max(snr, 1.0);
  return 1.5 / s * (1.0 + (15.0 / s) * (15.0 / s));
}

struct Link {
  PixelOffset step;    ///< from the earlier frame to the later, full-resolution px
  double snr = 0.0;
  double sigma = 0.0;  ///< 1-sigma error of the step per axis, full-resolution px (linkSigmaPx x bin)
  bool ok = false;
};

/// `guide`/`guideRadius` (full-resolution px): see correlate.
Link measureLink(const StarImages& images, std::size_t later, std::size_t earlier, double minSnr,
                 const std::optional<PixelOffset>& guide = std::nullopt, double guideRadius = 0.0) {
  const std::vector<float> a = images.make(later), b = images.make(earlier);
  Link l;
  std::optional<PixelOffset> g;
  if (guide) g = PixelOffset{guide->x / images.bin(), guide->y / images.bin()};
  bool atEdge = false;
  const PixelOffset s = correlate(a.data(), b.data(), images.width(), images.height(), images.weights(), l.snr,
                                  g, guideRadius / images.bin(), &atEdge);
  l.step = {s.x * images.bin(), s.y * images.bin()};
  l.sigma = linkSigmaPx(l.snr) * images.bin();
  l.ok = l.snr >= minSnr && !atEdge;
  return l;
}

/// A frame's departure from the model is used only beyond this many sigmas of its measurement.
constexpr double kSignificance = 5.0;

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

/// Theil-Sen slope of p over t (time order), pairs at most `maxGap` apart (subsampled to ~20000 pairs).
double theilSen(const std::vector<double>& t, const std::vector<double>& p, std::size_t maxGap) {
  const std::size_t n = t.size();
  std::vector<double> slopes;
  const std::size_t pairs = n * std::min(maxGap, n);
  const std::size_t stride = std::max<std::size_t>(1, pairs / 20000);
  std::size_t k = 0;
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = i + 1; j < n && j <= i + maxGap; ++j) {
      if (k++ % stride != 0 || !(t[j] > t[i])) continue;
      slopes.push_back((p[j] - p[i]) / (t[j] - t[i]));
    }
  }
  return median(std::move(slopes));
}

/// Prefix sums of one axis for the segmented fit: the common rate of p over t with one free level per
/// segment, its residual sum of squares in O(segments).
class SegmentFit {
 public:
  SegmentFit(const std::vector<double>& t, const std::vector<double>& p) : m_n(t.size()) {
    m_s.assign(5 * (m_n + 1), 0.0);
    for (std::size_t k = 0; k < m_n; ++k) {
      const double v[5] = {t[k], p[k], t[k] * t[k], t[k] * p[k], p[k] * p[k]};
      for (int j = 0; j < 5; ++j)
        m_s[5 * (k + 1) + j] = m_s[5 * k + j] + v[j];
    }
  }
  /// Rate and residual sum of squares for segments [cuts_i, cuts_i+1); sxx: the within-segment sum of
  /// (t - mean)^2 (the rate's variance is sigma^2 / sxx).
  [[nodiscard]] double fit(const std::vector<std::size_t>& cuts, double& rss, double& sxx) const {
    double sxy = 0.0, syy = 0.0;
    sxx = 0.0;
    for (std::size_t i = 0; i + 1 < cuts.size(); ++i) {
      const std::size_t a = cuts[i], b = cuts[i + 1];
      const double n = static_cast<double>(b - a);
      const auto sum = [&](int j) { return m_s[5 * b + j] - m_s[5 * a + j]; };
      sxx += sum(2) - sum(0) * sum(0) / n;
      sxy += sum(3) - sum(0) * sum(1) / n;
      syy += sum(4) - sum(1) * sum(1) / n;
    }
    const double rate = sxx > 0.0 ? sxy / sxx : 0.0;
    rss = std::max(0.0, syy - rate * sxy);
    return rate;
  }

 private:
  std::size_t m_n;
  std::vector<double> m_s;
};

/// The linear rate of the chained positions (time order) for the per-frame model: a common rate with a
/// level per pointing, the pointings found by binary segmentation (at most 4 re-pointings, at least 3
/// frames each; a cut is kept when it removes more than max(12, 4 ln N) sigma^2 of squared residual, sigma
/// the frame-to-frame scatter from the median of successive differences).
/// An axis whose rate is not significant (below 3 sigma) is 0: dithers and re-pointings of a tracked
/// telescope do not make the stars drift. `note` says what was found.
Velocity robustRate(const std::vector<double>& t, const std::vector<double>& px, const std::vector<double>& py,
                    std::string& note) {
  const std::size_t n = t.size();
  std::vector<double> d;
  for (std::size_t k = 1; k < n; ++k)
    d.push_back(std::hypot(px[k] - px[k - 1], py[k] - py[k - 1]));
  // The 2-D distance of two independent Gaussian scatters of sigma per axis has median 1.1774 sqrt(2) sigma.
  const double sigma = std::max(1e-3, median(d) / (1.1774 * std::sqrt(2.0)));
  const SegmentFit fx(t, px), fy(t, py);
  std::vector<std::size_t> cuts{0, n};
  // A cut adds a level per axis and a position: kept above max(12, 4 ln N) sigma^2 (random dithers alone
  // reach ~2 ln N + 2).
  const double cutGain = std::max(12.0, 4.0 * std::log(static_cast<double>(n)));
  const auto total = [&](const std::vector<std::size_t>& c) {
    double rx = 0.0, ry = 0.0, sxx = 0.0;
    (void)fx.fit(c, rx, sxx);
    (void)fy.fit(c, ry, sxx);
    return rx + ry;
  };
  double rss = total(cuts);
  for (int jumps = 0; jumps < 4; ++jumps) {
    double best = rss;
    std::vector<std::size_t> bestCuts;
    for (std::size_t i = 0; i + 1 < cuts.size(); ++i) {
      for (std::size_t m = cuts[i] + 3; m + 3 <= cuts[i + 1]; ++m) {
        std::vector<std::size_t> c = cuts;
        c.insert(c.begin() + static_cast<std::ptrdiff_t>(i) + 1, m);
        const double v = total(c);
        if (v < best) best = v, bestCuts = std::move(c);
      }
    }
    if (bestCuts.empty() || rss - best <= cutGain * sigma * sigma) break;
    cuts = std::move(bestCuts);
    rss = best;
  }
  double dummy = 0.0, sxx = 0.0;
  double rate[2] = {fx.fit(cuts, dummy, sxx), fy.fit(cuts, dummy, sxx)};
  const double sigmaRate = sxx > 0.0 ? sigma / std::sqrt(sxx) : 0.0;
  std::ostringstream s;
  s.precision(3);
  s << cuts.size() - 1 << " pointing(s)";
  const char* axis[2] = {"x", "y"};
  for (int a = 0; a < 2; ++a) {
    if (std::abs(rate[a]) < 3.0 * sigmaRate) {
      s << ", no significant drift along " << axis[a] << " (" << rate[a] << " +- " << sigmaRate << " px/s): 0";
      rate[a] = 0.0;
    }
  }
  note = s.str();
  return {rate[0], rate[1]};
}

std::string modelNote(const Registration& r, std::size_t frames) {
  std::ostringstream s;
  s.precision(3);
  switch (r.model) {
    case Registration::Model::Linear:
      s << "registration: the linear sky rate fits the star field of the " << frames << " frames (residual rms "
        << r.rmsPx << " px, max " << r.maxPx << " px";
      if (!r.position.empty()) s << "; no frame departs from it beyond its measurement error";
      s << ")";
      break;
    case Registration::Model::PerFrame:
      s << "registration: the linear sky rate (" << r.rate.vx << ", " << r.rate.vy
        << ") px/s leaves the star field off by rms " << r.rmsPx << " px, max " << r.maxPx
        << " px (dithers, guiding, re-pointing): per-frame offsets are used for the " << r.significantFrames
        << " frame(s) that depart from it significantly";
      if (!r.rateNote.empty()) s << " (" << r.rateNote << ")";
      break;
    case Registration::Model::Unmeasured:
      s << "registration: the star field could not be followed from frame to frame (" << r.linksMeasured
        << " significant links); the linear sky rate is the model";
      break;
  }
  return s.str();
}

}  // namespace

PixelOffset correlationStep(const float* a, const float* b, int width, int height, double& snr) {
  std::vector<float> sa(static_cast<std::size_t>(width) * height), sb(sa.size());
  const CorrelationWeights weights = correlationWeights(width, height);
  starImage(a, nullptr, width, height, 1, weights, sa.data());
  starImage(b, nullptr, width, height, 1, weights, sb.data());
  return correlate(sa.data(), sb.data(), width, height, weights, snr);
}

Registration measureRegistration(const FrameCube& cube, std::optional<Velocity> givenRate,
                                 const RegistrationParams& params, ProgressSink& progress,
                                 CancelToken& cancel) {
  Registration r;
  const std::size_t nf = cube.frameCount();
  r.offsets.assign(nf, PixelOffset{});
  if (nf < 3 || cube.width() < 16 || cube.height() < 16) {
    r.note = modelNote(r, nf);
    return r;
  }
  const std::vector<double> dt = cube.timeOffsetsS();
  std::vector<std::size_t> order(nf);
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return dt[a] < dt[b]; });
  const StarImages images(cube);

  // Long sequences: sampled links first; when they all follow one linear rate, that is the model.
  if (nf > 2 * kQuickFrames) {
    std::vector<Link> quick(kQuickFrames);
    std::vector<std::size_t> at(kQuickFrames);
    for (int i = 0; i < kQuickFrames; ++i)
      at[i] = (nf - 2) * static_cast<std::size_t>(i) / (kQuickFrames - 1);
    parallelFor(quick.size(), 1, [&](std::size_t b, std::size_t e) {
      for (std::size_t i = b; i < e; ++i) {
        cancel.throwIfCancelled();
        quick[i] = measureLink(images, order[at[i] + 1], order[at[i]], params.minPeakSnr);
      }
    });
    std::vector<double> rx, ry;
    for (int i = 0; i < kQuickFrames; ++i) {
      const double gap = dt[order[at[i] + 1]] - dt[order[at[i]]];
      if (!quick[i].ok || !(gap > 0.0)) continue;
      rx.push_back(quick[i].step.x / gap);
      ry.push_back(quick[i].step.y / gap);
      ++r.linksMeasured;
    }
    const Velocity rate = givenRate.value_or(Velocity{median(rx), median(ry)});
    bool linear = r.linksMeasured == kQuickFrames;
    double worst = 0.0, sum2 = 0.0;
    bool agree = true;  // each link within quickTolerancePx, or within its own measurement error
    for (int i = 0; i < kQuickFrames && linear; ++i) {
      const double gap = dt[order[at[i] + 1]] - dt[order[at[i]]];
      const double ex = quick[i].step.x - rate.vx * gap, ey = quick[i].step.y - rate.vy * gap;
      const double e = std::hypot(ex, ey);
      worst = std::max(worst, e);
      sum2 += ex * ex + ey * ey;
      agree = agree && e <= std::max(params.quickTolerancePx, kSignificance * quick[i].sigma);
    }
    if (r.linksMeasured < kQuickFrames / 2) {  // faint frames (EMCCD at 16.7 Hz): not worth every frame
      r.note = modelNote(r, nf) + " (" + std::to_string(kQuickFrames) + " sampled frame pairs)";
      return r;
    }
    if (linear && agree) {
      r.model = Registration::Model::Linear;
      r.rate = rate;
      r.rmsPx = std::sqrt(sum2 / kQuickFrames);
      r.maxPx = worst;
      r.note = modelNote(r, nf) + " (" + std::to_string(kQuickFrames) + " sampled frame pairs)";
      return r;
    }
    r.linksMeasured = 0;
  }

  // Every frame linked to its predecessor in time (to an earlier one when that link fails).
  std::vector<Link> links(nf);
  std::vector<int> back(nf, 1);
  std::atomic<std::size_t> done{0};
  parallelFor(nf - 1, 1, [&](std::size_t b, std::size_t e) {
    for (std::size_t k = b + 1; k < e + 1; ++k) {
      cancel.throwIfCancelled();
      for (int d = 1; d <= kMaxBack && d <= static_cast<int>(k); ++d) {
        links[k] = measureLink(images, order[k], order[k - d], params.minPeakSnr);
        back[k] = d;
        if (links[k].ok) break;
      }
      progress.report(static_cast<double>(done.fetch_add(1) + 1) / static_cast<double>(nf - 1),
                      "registration");
    }
  });
  std::vector<double> px(nf, 0.0), py(nf, 0.0), t(nf, 0.0);
  bool complete = true;
  for (std::size_t k = 0; k < nf; ++k) {
    t[k] = dt[order[k]];
    if (k == 0) continue;
    if (!links[k].ok) {
      complete = false;
      continue;
    }
    ++r.linksMeasured;
    px[k] = px[k - back[k]] + links[k].step.x;
    py[k] = py[k - back[k]] + links[k].step.y;
  }
  if (!complete) {
    r.note = modelNote(r, nf);
    return r;
  }
  // Second pass, against anchors: every frame measured directly against the last anchor frame whose field it
  // still largely shares (chained positions within 0.4 of the frame), anchors linked to each other,
  // so the errors of the neighbour chain do not add up over the whole sequence (sidereal data: one anchor).
  const double reach = 0.4 * std::min(cube.width(), cube.height());
  std::vector<std::size_t> anchorOf(nf, 0);
  std::vector<std::size_t> anchors{0};
  for (std::size_t k = 1; k < nf; ++k) {
    const std::size_t a = anchors.back();
    if (std::hypot(px[k] - px[a], py[k] - py[a]) > reach) anchors.push_back(k - 1);
    anchorOf[k] = anchors.back();
  }
  // anchorOf[k] < k: an anchor frame itself is measured against the anchor before it.
  std::vector<Link> direct(nf);
  std::vector<double> posVar(nf, 0.0);  ///< variance of P_k (per axis, px^2) from the links that gave it
  // Variance of the chained position (per axis) and of the chained step between two frames: along the
  // back-pointer tree, through the frames' common ancestor.
  std::vector<double> chainVar(nf, 0.0);
  for (std::size_t k = 1; k < nf; ++k)
    chainVar[k] = chainVar[k - back[k]] + links[k].sigma * links[k].sigma;
  const auto chainStepVar = [&](std::size_t i, std::size_t j) {
    std::size_t a = i, b = j;
    while (a != b) {
      if (a > b) {
        a -= static_cast<std::size_t>(back[a]);
      } else {
        b -= static_cast<std::size_t>(back[b]);
      }
    }
    return std::max(0.0, chainVar[i] + chainVar[j] - 2.0 * chainVar[a]);
  };
  parallelFor(nf - 1, 1, [&](std::size_t b, std::size_t e) {
    for (std::size_t k = b + 1; k < e + 1; ++k) {
      cancel.throwIfCancelled();
      const std::size_t ref = anchorOf[k];
      if (ref + back[k] == k) {
        direct[k] = links[k];
        continue;
      }
      // Guided by the chained step: within 3 px plus 4 sigma of the chain between the two frames plus 2% of
      // the distance; a best pixel on the disk's rim is not taken (the link falls back to the chain).
      const PixelOffset chained{px[k] - px[ref], py[k] - py[ref]};
      const double radius =
          3.0 + 4.0 * std::sqrt(2.0 * chainStepVar(k, ref)) + 0.02 * std::hypot(chained.x, chained.y);
      direct[k] = measureLink(images, order[k], order[ref], params.minPeakSnr, chained, radius);
    }
  });
  {
    std::vector<double> qx(px), qy(py);
    for (std::size_t k = 1; k < nf; ++k) {
      const std::size_t ref = anchorOf[k];
      if (direct[k].ok) {
        qx[k] = qx[ref] + direct[k].step.x;
        qy[k] = qy[ref] + direct[k].step.y;
        posVar[k] = posVar[ref] + direct[k].sigma * direct[k].sigma;
      } else {  // the chained step from the anchor
        qx[k] = qx[ref] + (px[k] - px[ref]);
        qy[k] = qy[ref] + (py[k] - py[ref]);
        posVar[k] = posVar[ref] + chainStepVar(k, ref);
      }
    }
    px = std::move(qx);
    py = std::move(qy);
  }
  const std::size_t gapPairs = std::max<std::size_t>(1, nf / 4);
  r.position.assign(nf, PixelOffset{});
  for (std::size_t k = 0; k < nf; ++k)
    r.position[order[k]] = {px[k], py[k]};
  // Residuals from a rate, o_0 = 0 (frame 0 keeps the WCS's mapping); rms about their own mean (a constant
  // offset is no departure from a linear motion), largest.
  std::vector<PixelOffset> resid(nf);
  const auto residuals = [&](Velocity rate) {
    double mx = 0.0, my = 0.0;
    r.maxPx = 0.0;
    for (std::size_t k = 0; k < nf; ++k) {
      const PixelOffset o{px[k] - rate.vx * (t[k] - t[0]), py[k] - rate.vy * (t[k] - t[0])};
      resid[order[k]] = o;
      mx += o.x / static_cast<double>(nf), my += o.y / static_cast<double>(nf);
    }
    double var = 0.0;
    for (const auto& o : resid) {
      var += (o.x - mx) * (o.x - mx) + (o.y - my) * (o.y - my);
      r.maxPx = std::max(r.maxPx, std::hypot(o.x - mx, o.y - my));
    }
    r.rmsPx = std::sqrt(var / static_cast<double>(nf));
  };
  r.rate = givenRate.value_or(Velocity{theilSen(t, px, gapPairs), theilSen(t, py, gapPairs)});
  residuals(r.rate);
  if (r.rmsPx > params.linearRmsPx && !givenRate) {
    r.rate = robustRate(t, px, py, r.rateNote);
    residuals(r.rate);
  }
  // Per-frame offsets only where the departure from the linear model is significant against the frame's
  // own measurement error (kSignificance sigma, propagated along the links that placed it): frames whose
  // star field is faint or changing are measured at low peak significance, and their scatter is no
  // pointing jump (paper-neo seed 25: links at SNR 8-12 in its first 40 frames gave rms 1.8 px of false
  // "pointings"). Insignificant departures keep the linear model (o_n = 0).
  std::size_t significant = 0;
  for (std::size_t k = 0; k < nf; ++k) {
    PixelOffset& o = resid[order[k]];
    // |o| of two axes, each of variance posVar: its scale is sqrt(2 posVar).
    if (std::hypot(o.x, o.y) > kSignificance * std::sqrt(2.0 * posVar[k])) {
      ++significant;
    } else {
      o = {};
    }
  }
  r.significantFrames = static_cast<int>(significant);
  if (r.rmsPx <= params.linearRmsPx || significant == 0) {
    r.model = Registration::Model::Linear;
  } else {
    r.model = Registration::Model::PerFrame;
    r.offsets = std::move(resid);
  }
  r.note = modelNote(r, nf);
  return r;
}

void applyRegistration(FrameCube& cube, const Registration& reg) {
  auto& info = cube.info();
  const bool use = reg.model == Registration::Model::PerFrame && reg.offsets.size() == info.size();
  for (std::size_t n = 0; n < info.size(); ++n) {
    info[n].offsetXPx = use ? reg.offsets[n].x : 0.0;
    info[n].offsetYPx = use ? reg.offsets[n].y : 0.0;
  }
}

}  // namespace st::detect

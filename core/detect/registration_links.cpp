#include "registration_links.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <utility>

#include "st/common/fftw_plans.hpp"

namespace st::detect {
namespace {

constexpr float kClipSigma =
    30.0f;  ///< a star image's pixels are clipped here (bright stars do not dominate)
constexpr float kFloorSigma = 2.5f;  ///< and zeroed below this (the noise does not correlate)
constexpr int kBinAbove = 1024;      ///< frames wider or taller than this are binned 2x2 first
constexpr int kTaperPx = 24;         ///< star images fade to 0 over this band at the edges (at most 1/8 side)
constexpr double kHighPassPx = 12.0;  ///< structure wider than this (a saturated star's clipped disk) is
                                      ///< filtered out of the correlation: point-like stars set the peak

using detail::CorrelationWeights;
using fftw::CplxBuf;
using fftw::RealBuf;

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
  const double sx = 2.0 * M_PI / w, sy = 2.0 * M_PI / h,
               scale2 = kHighPassPx * kHighPassPx / (4.0 * M_PI * M_PI);
  cw.highPass.resize(static_cast<std::size_t>(hw) * h);
  for (int ky = 0; ky < h; ++ky) {
    const int fy = ky <= h / 2 ? ky : ky - h;
    const double ky2 = (sy * fy) * (sy * fy);
    for (int kx = 0; kx < hw; ++kx) {
      const double k2 = ky2 + (sx * kx) * (sx * kx);
      // The row ky = 0 (structure constant along y: a column pattern fixed on the detector, whose thresholded
      // noise makes a ridge along step x = 0 of the surface) and the column kx = 0 (a row pattern) are left
      // out (paper-neo's 2 ADU bias columns under 27.7 ADU of noise pulled neighbouring frames' ~1 px steps
      // towards 0: seed 37's chain drifted 3 px and made false pointings; test_registration).
      cw.highPass[static_cast<std::size_t>(ky) * hw + kx] =
          ky == 0 || kx == 0 ? 0.0f : static_cast<float>(1.0 - std::exp(-0.5 * k2 * scale2));
    }
  }
  return cw;
}

/// The star image of one frame (model in the header), binned by `bin`, into `out` (w/bin x h/bin), tapered
/// at the edges with `weights` (made for w/bin x h/bin).
void starImage(const float* f, const std::uint8_t* mask, int w, int h, int bin,
               const CorrelationWeights& weights, float* out) {
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

}  // namespace

namespace detail {

StarImages::StarImages(const FrameCube& cube, FrameGate gate) : m_cube(cube), m_gate(std::move(gate)) {
  m_bin = std::max(cube.width(), cube.height()) > kBinAbove ? 2 : 1;
  m_w = cube.width() / m_bin;
  m_h = cube.height() / m_bin;
  m_weights = correlationWeights(m_w, m_h);
}

std::vector<float> StarImages::make(std::size_t n) const {
  if (m_gate) m_gate(n);
  std::vector<float> out(static_cast<std::size_t>(m_w) * m_h);
  const auto& mask = m_cube.mask();
  starImage(m_cube.frame(n), mask.empty() ? nullptr : mask.data() + n * m_cube.framePixels(), m_cube.width(),
            m_cube.height(), m_bin, m_weights, out.data());
  return out;
}

double linkSigmaPx(double snr) {
  const double s = std::max(snr, 1.0);
  return 1.5 / s * (1.0 + (15.0 / s) * (15.0 / s));
}

Link measureLink(const StarImages& images, std::size_t later, std::size_t earlier, double minSnr,
                 const std::optional<PixelOffset>& guide, double guideRadius) {
  const std::vector<float> a = images.make(later), b = images.make(earlier);
  Link l;
  std::optional<PixelOffset> g;
  if (guide) g = PixelOffset{guide->x / images.bin(), guide->y / images.bin()};
  bool atEdge = false;
  const PixelOffset s = correlate(a.data(), b.data(), images.width(), images.height(), images.weights(),
                                  l.snr, g, guideRadius / images.bin(), &atEdge);
  l.step = {s.x * images.bin(), s.y * images.bin()};
  l.sigma = linkSigmaPx(l.snr) * images.bin();
  l.ok = l.snr >= minSnr && !atEdge;
  return l;
}

Link linkFromPeak(const StarImages& images, const RegistrationLinkPeak& peak, double minSnr) {
  Link l;
  l.snr = peak.snr;
  l.step = {peak.dx * images.bin(), peak.dy * images.bin()};
  l.sigma = linkSigmaPx(l.snr) * images.bin();
  l.ok = l.snr >= minSnr;
  return l;
}

}  // namespace detail

PixelOffset correlationStep(const float* a, const float* b, int width, int height, double& snr) {
  std::vector<float> sa(static_cast<std::size_t>(width) * height), sb(sa.size());
  const CorrelationWeights weights = correlationWeights(width, height);
  starImage(a, nullptr, width, height, 1, weights, sa.data());
  starImage(b, nullptr, width, height, 1, weights, sb.data());
  return correlate(sa.data(), sb.data(), width, height, weights, snr);
}

}  // namespace st::detect

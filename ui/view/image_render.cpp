#include "image_render.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

namespace st::ui {
namespace {

struct Anchor {
  double t, r, g, b;
};

// matplotlib's viridis and inferno at t = k/9 (its ten-colour palettes), linearly interpolated to 256
// entries.
constexpr Anchor kViridis[] = {
    {0.0 / 9, 68 / 255.0, 1 / 255.0, 84 / 255.0},    {1.0 / 9, 72 / 255.0, 40 / 255.0, 120 / 255.0},
    {2.0 / 9, 62 / 255.0, 74 / 255.0, 137 / 255.0},  {3.0 / 9, 49 / 255.0, 104 / 255.0, 142 / 255.0},
    {4.0 / 9, 38 / 255.0, 130 / 255.0, 142 / 255.0}, {5.0 / 9, 31 / 255.0, 158 / 255.0, 137 / 255.0},
    {6.0 / 9, 53 / 255.0, 183 / 255.0, 121 / 255.0}, {7.0 / 9, 110 / 255.0, 206 / 255.0, 88 / 255.0},
    {8.0 / 9, 181 / 255.0, 222 / 255.0, 43 / 255.0}, {9.0 / 9, 253 / 255.0, 231 / 255.0, 37 / 255.0}};
constexpr Anchor kInferno[] = {
    {0.0 / 9, 0 / 255.0, 0 / 255.0, 4 / 255.0},      {1.0 / 9, 27 / 255.0, 12 / 255.0, 65 / 255.0},
    {2.0 / 9, 74 / 255.0, 12 / 255.0, 107 / 255.0},  {3.0 / 9, 120 / 255.0, 28 / 255.0, 109 / 255.0},
    {4.0 / 9, 165 / 255.0, 44 / 255.0, 96 / 255.0},  {5.0 / 9, 207 / 255.0, 68 / 255.0, 70 / 255.0},
    {6.0 / 9, 237 / 255.0, 105 / 255.0, 37 / 255.0}, {7.0 / 9, 251 / 255.0, 155 / 255.0, 6 / 255.0},
    {8.0 / 9, 247 / 255.0, 209 / 255.0, 61 / 255.0}, {9.0 / 9, 252 / 255.0, 255 / 255.0, 164 / 255.0}};

template <std::size_t N>
std::array<QRgb, 256> interpolate(const Anchor (&anchors)[N]) {
  std::array<QRgb, 256> out{};
  for (int i = 0; i < 256; ++i) {
    const double t = i / 255.0;
    std::size_t k = 0;
    while (k + 2 < N && anchors[k + 1].t < t)
      ++k;
    const Anchor& a = anchors[k];
    const Anchor& b = anchors[k + 1];
    const double f = std::clamp((t - a.t) / (b.t - a.t), 0.0, 1.0);
    auto c = [&](double x, double y) { return static_cast<int>(std::lround(255.0 * (x + f * (y - x)))); };
    out[static_cast<std::size_t>(i)] = qRgb(c(a.r, b.r), c(a.g, b.g), c(a.b, b.b));
  }
  return out;
}

std::array<QRgb, 256> grayTable() {
  std::array<QRgb, 256> out{};
  for (int i = 0; i < 256; ++i)
    out[static_cast<std::size_t>(i)] = qRgb(i, i, i);
  return out;
}

// Up to `maxCount` finite values taken at a regular stride (zscale's sampling).
std::vector<float> sample(const float* data, std::size_t n, std::size_t maxCount) {
  std::vector<float> out;
  const std::size_t stride = std::max<std::size_t>(1, n / maxCount);
  out.reserve(std::min(n, maxCount) + 1);
  for (std::size_t i = 0; i < n; i += stride) {
    if (std::isfinite(data[i])) out.push_back(data[i]);
  }
  return out;
}

std::pair<double, double> zscale(std::vector<float>& s) {
  std::sort(s.begin(), s.end());
  const auto n = static_cast<long>(s.size());
  const double median = s[static_cast<std::size_t>(n / 2)];
  // Iteratively fit value = a + b * (i - centre) to the unrejected points, rejecting > 2.5 sigma.
  std::vector<bool> keep(static_cast<std::size_t>(n), true);
  double slope = 0.0;
  double intercept = median;
  const double centre = 0.5 * static_cast<double>(n - 1);
  for (int iter = 0; iter < 5; ++iter) {
    double sx = 0, sy = 0, sxx = 0, sxy = 0, cnt = 0;
    for (long i = 0; i < n; ++i) {
      if (!keep[static_cast<std::size_t>(i)]) continue;
      const double x = static_cast<double>(i) - centre;
      const double y = s[static_cast<std::size_t>(i)];
      sx += x, sy += y, sxx += x * x, sxy += x * y, cnt += 1;
    }
    if (cnt < 0.5 * static_cast<double>(n)) break;  // IRAF: give up when more than half rejected
    const double det = cnt * sxx - sx * sx;
    if (det <= 0) break;
    slope = (cnt * sxy - sx * sy) / det;
    intercept = (sy - slope * sx) / cnt;
    double ss = 0;
    for (long i = 0; i < n; ++i) {
      if (!keep[static_cast<std::size_t>(i)]) continue;
      const double r =
          s[static_cast<std::size_t>(i)] - (intercept + slope * (static_cast<double>(i) - centre));
      ss += r * r;
    }
    const double sigma = std::sqrt(ss / cnt);
    bool changed = false;
    for (long i = 0; i < n; ++i) {
      const double r =
          s[static_cast<std::size_t>(i)] - (intercept + slope * (static_cast<double>(i) - centre));
      const bool k = std::abs(r) <= 2.5 * sigma;
      if (keep[static_cast<std::size_t>(i)] != k) changed = true;
      keep[static_cast<std::size_t>(i)] = k;
    }
    if (!changed) break;
  }
  const double contrast = 0.25;
  const double slopeZ = slope / contrast;
  const double lo = std::max<double>(s.front(), median - centre * slopeZ);
  const double hi = std::min<double>(s.back(), median + centre * slopeZ);
  return {lo, hi};
}

}  // namespace

const std::array<QRgb, 256>& colormapTable(Colormap map) {
  static const std::array<QRgb, 256> gray = grayTable();
  static const std::array<QRgb, 256> viridis = interpolate(kViridis);
  static const std::array<QRgb, 256> inferno = interpolate(kInferno);
  switch (map) {
    case Colormap::Viridis:
      return viridis;
    case Colormap::Inferno:
      return inferno;
    case Colormap::Gray:
      break;
  }
  return gray;
}

QString toString(Stretch s) {
  switch (s) {
    case Stretch::Log:
      return "log";
    case Stretch::Asinh:
      return "asinh";
    case Stretch::Linear:
      break;
  }
  return "linear";
}

QString toString(LimitsMode m) {
  switch (m) {
    case LimitsMode::Percentile:
      return "percentile";
    case LimitsMode::MinMax:
      return "min/max";
    case LimitsMode::ZScale:
      break;
  }
  return "zscale";
}

QString toString(Colormap c) {
  switch (c) {
    case Colormap::Viridis:
      return "viridis";
    case Colormap::Inferno:
      return "inferno";
    case Colormap::Gray:
      break;
  }
  return "gray";
}

std::pair<double, double> computeLimits(const float* data, std::size_t n, const DisplaySettings& settings) {
  std::vector<float> s = sample(data, n, settings.limits == LimitsMode::ZScale ? 20000 : 200000);
  if (s.empty()) return {0.0, 1.0};
  double lo = 0.0;
  double hi = 0.0;
  if (settings.limits == LimitsMode::ZScale && s.size() >= 5) {
    std::tie(lo, hi) = zscale(s);
  } else if (settings.limits == LimitsMode::Percentile) {
    const double p = std::clamp(settings.percentile, 50.0, 100.0) / 100.0;
    auto at = [&](double q) {
      const auto k = static_cast<std::size_t>(std::lround(q * static_cast<double>(s.size() - 1)));
      std::nth_element(s.begin(), s.begin() + static_cast<long>(k), s.end());
      return static_cast<double>(s[k]);
    };
    lo = at(1.0 - p);
    hi = at(p);
  } else {
    const auto [mn, mx] = std::minmax_element(s.begin(), s.end());
    lo = *mn;
    hi = *mx;
  }
  if (!(hi > lo)) hi = lo + 1.0;
  return {lo, hi};
}

double stretchValue(double value, double lo, double hi, Stretch stretch) {
  const double t = std::clamp((value - lo) / (hi - lo), 0.0, 1.0);
  switch (stretch) {
    case Stretch::Log:
      return std::log10(1.0 + 1000.0 * t) / 3.0;
    case Stretch::Asinh:
      return std::asinh(10.0 * t) / std::asinh(10.0);
    case Stretch::Linear:
      break;
  }
  return t;
}

QImage renderImage(const Image& image, double lo, double hi, const DisplaySettings& settings) {
  QImage out(image.width, image.height, QImage::Format_RGB32);
  if (image.empty()) return out;
  const auto& table = colormapTable(settings.colormap);
  // A 4096-entry lookup of the stretch keeps the per-pixel work to one multiply and two loads.
  constexpr int kLevels = 4096;
  std::array<QRgb, kLevels> lut{};
  for (int i = 0; i < kLevels; ++i) {
    const double v = lo + (hi - lo) * i / (kLevels - 1.0);
    const double d = stretchValue(v, lo, hi, settings.stretch);
    lut[static_cast<std::size_t>(i)] = table[static_cast<std::size_t>(std::lround(d * 255.0))];
  }
  const float scale = static_cast<float>((kLevels - 1) / (hi - lo));
  const auto flo = static_cast<float>(lo);
  const QRgb nanColour = qRgb(120, 0, 0);
  for (int y = 0; y < image.height; ++y) {
    auto* line = reinterpret_cast<QRgb*>(out.scanLine(image.height - 1 - y));
    const float* row = image.data() + static_cast<std::size_t>(y) * image.width;
    for (int x = 0; x < image.width; ++x) {
      const float v = row[x];
      if (!std::isfinite(v)) {
        line[x] = nanColour;
        continue;
      }
      const float f = std::clamp((v - flo) * scale + 0.5f, 0.0f, static_cast<float>(kLevels - 1));
      line[x] = lut[static_cast<std::size_t>(f)];
    }
  }
  return out;
}

}  // namespace st::ui

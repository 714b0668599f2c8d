#include "scene.hpp"

#include <algorithm>
#include <cmath>

#include "st/common/units.hpp"
#include "st/sim/samplers.hpp"

namespace st::sim::detail {

namespace {

constexpr double kStarMarginPx = 12.0;
constexpr double kBrightStarMinSeparationPx = 40.0;

double powerLawMagnitude(Rng& rng, double mMin, double mMax) {
  // N(<m) proportional to 10^(0.3 m): inverse CDF.
  const double a = std::pow(10.0, 0.3 * mMin);
  const double b = std::pow(10.0, 0.3 * mMax);
  return std::log10(a + uniform01(rng) * (b - a)) / 0.3;
}

// Closest approach over the observation between a star and an object (relative motion is linear).
double closestApproachPx(const SimParams& p, const Scene& s, double sx, double sy, const TruthObject& o) {
  const double rx = sx - o.xRefPx;
  const double ry = sy - o.yRefPx;
  const double wx = p.skyDriftXPxPerS - o.vxPxPerS;
  const double wy = p.skyDriftYPxPerS - o.vyPxPerS;
  const double t0 = s.tOffsetS.front();
  const double t1 = s.tOffsetS.back();
  const double w2 = wx * wx + wy * wy;
  double t = w2 > 0.0 ? -(rx * wx + ry * wy) / w2 : 0.0;
  t = std::clamp(t, t0, t1);
  return std::hypot(rx + wx * t, ry + wy * t);
}

void planTimes(const SimParams& p, Scene& s) {
  s.mjdMid.resize(p.frames);
  double sum = 0.0;
  for (int n = 0; n < p.frames; ++n) {
    const double startS = n / p.frameRateHz;
    s.mjdMid[n] = p.startMjd + (startS + 0.5 * p.exposureS) / kSecondsPerDay;
    sum += startS + 0.5 * p.exposureS;
  }
  const double meanS = sum / p.frames;
  s.tRefMjd = p.startMjd + meanS / kSecondsPerDay;
  s.tOffsetS.resize(p.frames);
  for (int n = 0; n < p.frames; ++n)
    s.tOffsetS[n] = n / p.frameRateHz + 0.5 * p.exposureS - meanS;
}

void planCalibration(const SimParams& p, std::uint64_t seed, Scene& s) {
  Rng flatRng(streamSeed(seed, kStreamFlat));
  s.flat = Image(p.width, p.height, 1.0f);
  const double cx = 0.5 * (p.width - 1), cy = 0.5 * (p.height - 1);
  const double r2max = cx * cx + cy * cy + 1.0;
  double sum = 0.0;
  std::vector<double> f(s.flat.size());
  for (int y = 0; y < p.height; ++y) {
    for (int x = 0; x < p.width; ++x) {
      const double r2 = ((x - cx) * (x - cx) + (y - cy) * (y - cy)) / r2max;
      const double v = (1.0 - 0.03 * r2) * (1.0 + p.flatAmplitude * normal01(flatRng));
      f[static_cast<std::size_t>(y) * p.width + x] = std::max(v, 0.05);
      sum += f[static_cast<std::size_t>(y) * p.width + x];
    }
  }
  const double mean = sum / static_cast<double>(f.size());
  for (std::size_t k = 0; k < f.size(); ++k)
    s.flat.pixels[k] = static_cast<float>(f[k] / mean);

  Rng biasRng(streamSeed(seed, kStreamBias));
  s.bias = Image(p.width, p.height);
  std::vector<double> column(p.width);
  for (auto& c : column)
    c = p.biasColumnPatternAdu * normal01(biasRng);
  for (int y = 0; y < p.height; ++y) {
    for (int x = 0; x < p.width; ++x)
      s.bias.at(x, y) = static_cast<float>(p.biasLevelAdu + column[x]);
  }
}

void planObjects(const SimParams& p, Scene& s) {
  for (const auto& o : p.objects) {
    TruthObject t;
    t.name = o.name;
    t.xRefPx = o.xRefPx;
    t.yRefPx = o.yRefPx;
    t.skyVxPxPerS = o.skyVxPxPerS;
    t.skyVyPxPerS = o.skyVyPxPerS;
    t.vxPxPerS = o.skyVxPxPerS + p.skyDriftXPxPerS;
    t.vyPxPerS = o.skyVyPxPerS + p.skyDriftYPxPerS;
    t.rateDegPerDay = pxPerSecToDegPerDay(std::hypot(t.skyVxPxPerS, t.skyVyPxPerS), p.plateScaleArcsecPerPx);
    t.frameRateDegPerDay = pxPerSecToDegPerDay(std::hypot(t.vxPxPerS, t.vyPxPerS), p.plateScaleArcsecPerPx);
    t.magnitude = o.magnitude;
    t.photonsPerFrame = photonsPerFrame(p, o.magnitude);
    s.objects.push_back(t);
  }
}

bool starAllowed(const SimParams& p, const Scene& s, double x, double y, double minSep) {
  if (minSep <= 0.0) return true;
  for (const auto& o : s.objects) {
    if (closestApproachPx(p, s, x, y, o) < minSep) return false;
  }
  return true;
}

TruthStar makeStar(const SimParams& p, double x, double y, double mag) {
  TruthStar star;
  star.xRefPx = x;
  star.yRefPx = y;
  star.magnitude = mag;
  star.photonsPerFrame = photonsPerFrame(p, mag);
  star.spikes = mag < p.spikeMagLimit && p.spikeFraction > 0.0;
  return star;
}

void planStars(const SimParams& p, std::uint64_t seed, Scene& s) {
  for (const auto& f : p.fixedStars)
    s.stars.push_back(makeStar(p, f.xRefPx, f.yRefPx, f.magnitude));
  Rng rng(streamSeed(seed, kStreamStars));
  // Stars visible at some time: x_ref in the frame widened by the drift over the observation.
  const double t0 = s.tOffsetS.front(), t1 = s.tOffsetS.back();
  const double dx0 = std::min(p.skyDriftXPxPerS * t0, p.skyDriftXPxPerS * t1);
  const double dx1 = std::max(p.skyDriftXPxPerS * t0, p.skyDriftXPxPerS * t1);
  const double dy0 = std::min(p.skyDriftYPxPerS * t0, p.skyDriftYPxPerS * t1);
  const double dy1 = std::max(p.skyDriftYPxPerS * t0, p.skyDriftYPxPerS * t1);
  const double xLo = -kStarMarginPx - dx1, xHi = p.width + kStarMarginPx - dx0;
  const double yLo = -kStarMarginPx - dy1, yHi = p.height + kStarMarginPx - dy0;
  const double areaRatio = (xHi - xLo) * (yHi - yLo) / (static_cast<double>(p.width) * p.height);
  const int count = static_cast<int>(std::lround(p.starCount * areaRatio));
  const int extra = std::max(0, p.brightStars);
  for (int k = 0; k < count + extra; ++k) {
    const bool bright = k >= count;
    double x = 0.0, y = 0.0;
    const double minSep =
        bright ? std::max(p.starMinSeparationPx, kBrightStarMinSeparationPx) : p.starMinSeparationPx;
    for (int attempt = 0; attempt < 100; ++attempt) {
      if (bright) {  // bright stars cross the frame: place them where they are seen for half the time
        x = xLo + (0.3 + 0.4 * uniform01(rng)) * (xHi - xLo);
        y = yLo + (0.3 + 0.4 * uniform01(rng)) * (yHi - yLo);
      } else {
        x = xLo + uniform01(rng) * (xHi - xLo);
        y = yLo + uniform01(rng) * (yHi - yLo);
      }
      if (starAllowed(p, s, x, y, minSep)) break;
    }
    const double mag = bright
                           ? p.brightStarMagMin + uniform01(rng) * (p.brightStarMagMax - p.brightStarMagMin)
                           : powerLawMagnitude(rng, p.starMagMin, p.starMagMax);
    s.stars.push_back(makeStar(p, x, y, mag));
  }
}

void planCosmicRays(const SimParams& p, std::uint64_t seed, Scene& s) {
  Rng rng(streamSeed(seed, kStreamCosmic));
  s.cosmicByFrame.assign(p.frames, {});
  for (int n = 0; n < p.frames; ++n) {
    const auto hits = poisson(rng, p.cosmicRaysPerFrame);
    for (std::int64_t h = 0; h < hits; ++h) {
      CosmicRayPlan cr;
      cr.truth.frame = n;
      const int x = static_cast<int>(uniform01(rng) * p.width);
      const int y = static_cast<int>(uniform01(rng) * p.height);
      cr.truth.xPx = x;
      cr.truth.yPx = y;
      cr.truth.peakAdu = p.cosmicRayMinAdu * std::pow(p.cosmicRayMaxAdu / p.cosmicRayMinAdu, uniform01(rng));
      // A single pixel, a pair, or a short track of up to 5 px in a random direction.
      const double kind = uniform01(rng);
      const int length = kind < 0.4 ? 1 : (kind < 0.7 ? 2 : 3 + static_cast<int>(uniform01(rng) * 3));
      const double angle = 2.0 * M_PI * uniform01(rng);
      for (int k = 0; k < length; ++k) {
        const int px = x + static_cast<int>(std::lround(k * std::cos(angle)));
        const int py = y + static_cast<int>(std::lround(k * std::sin(angle)));
        if (px < 0 || py < 0 || px >= p.width || py >= p.height) continue;
        const bool seen = std::any_of(cr.truth.pixels.begin(), cr.truth.pixels.end(),
                                      [&](const auto& q) { return q.first == px && q.second == py; });
        if (seen) continue;
        cr.truth.pixels.emplace_back(px, py);
        cr.amplitudesAdu.push_back(k == 0 ? cr.truth.peakAdu
                                          : cr.truth.peakAdu * (0.3 + 0.6 * uniform01(rng)));
      }
      s.cosmicByFrame[n].push_back(s.cosmic.size());
      s.cosmic.push_back(std::move(cr));
    }
  }
}

void planHotPixels(const SimParams& p, std::uint64_t seed, Scene& s) {
  Rng rng(streamSeed(seed, kStreamHot));
  for (int k = 0; k < p.hotPixels; ++k) {
    TruthHotPixel h;
    h.x = static_cast<int>(uniform01(rng) * p.width);
    h.y = static_cast<int>(uniform01(rng) * p.height);
    const bool seen =
        std::any_of(s.hot.begin(), s.hot.end(), [&](const auto& o) { return o.x == h.x && o.y == h.y; });
    if (seen) continue;
    h.excessAdu = p.hotPixelMinAdu * std::pow(p.hotPixelMaxAdu / p.hotPixelMinAdu, uniform01(rng));
    s.hot.push_back(h);
  }
}

}  // namespace

double photonsPerFrame(const SimParams& p, double mag) {
  return p.zeroPointPhotonsPerS * std::pow(10.0, -0.4 * mag) * p.exposureS;
}

Scene planScene(const SimParams& params, std::uint64_t seed) {
  Scene s;
  planTimes(params, s);
  planCalibration(params, seed, s);
  planObjects(params, s);
  planStars(params, seed, s);
  planCosmicRays(params, seed, s);
  planHotPixels(params, seed, s);
  return s;
}

double calibratedSigmaAdu(const SimParams& p, const Image& flat) {
  const double excess2 = p.emGain > 1.0 ? 2.0 : 1.0;
  const double g = p.emGain > 1.0 ? p.emGain : 1.0;
  double sum = 0.0;
  for (const float f : flat.pixels) {
    // (raw - bias) / flat: variance of the output electrons divided by (gain * flat)^2.
    const double varE = excess2 * g * g * f * p.skyPhotonsPerPxPerFrame + p.readNoiseE * p.readNoiseE;
    sum += varE / (static_cast<double>(f) * f);
  }
  const double n = flat.empty() ? 1.0 : static_cast<double>(flat.size());
  if (flat.empty()) sum = excess2 * g * g * p.skyPhotonsPerPxPerFrame + p.readNoiseE * p.readNoiseE;
  return std::sqrt(sum / n) / p.gainEPerAdu;
}

}  // namespace st::sim::detail

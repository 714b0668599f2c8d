#include "frame_renderer.hpp"

#include <algorithm>
#include <cmath>

namespace st::sim::detail {

namespace {

constexpr int kSpikeLengthPx = 48;
constexpr double kSpikeCoreRadiusPx = 3.0;

void splat(std::vector<double>& img, int w, int h, double x, double y, double flux) {
  const double fx = std::floor(x), fy = std::floor(y);
  const int ix = static_cast<int>(fx), iy = static_cast<int>(fy);
  const double ax = x - fx, ay = y - fy;
  const double wts[4] = {(1 - ax) * (1 - ay), ax * (1 - ay), (1 - ax) * ay, ax * ay};
  const int dx[4] = {0, 1, 0, 1};
  const int dy[4] = {0, 0, 1, 1};
  for (int k = 0; k < 4; ++k) {
    const int px = ix + dx[k], py = iy + dy[k];
    if (px >= 0 && py >= 0 && px < w && py < h) img[static_cast<std::size_t>(py) * w + px] += flux * wts[k];
  }
}

}  // namespace

FrameRenderer::FrameRenderer(const SimParams& params, const Scene& scene)
    : m_p(params),
      m_s(scene),
      m_starStamp(params.psf, params.skyDriftXPxPerS * params.exposureS,
                  params.skyDriftYPxPerS * params.exposureS, kStarStampRadiusPx) {
  for (const auto& o : scene.objects) {
    m_objectStamps.emplace_back(params.psf, o.vxPxPerS * params.exposureS, o.vyPxPerS * params.exposureS,
                                kObjectStampRadiusPx);
  }
  for (const auto& star : scene.stars) {
    m_starRadius.push_back(m_starStamp.radiusFor(star.photonsPerFrame, kStampFloorPhotons));
  }
}

void FrameRenderer::addSpikes(std::vector<double>& photons, double x, double y, double flux) const {
  // Four spikes along +-x and +-y; flux per px along a spike ~ 1 / (1 + (d / d0)^2).
  double norm = 0.0;
  for (int d = 1; d <= kSpikeLengthPx; ++d)
    norm += 1.0 / (1.0 + (d / kSpikeCoreRadiusPx) * (d / kSpikeCoreRadiusPx));
  const double perArm = flux / (4.0 * norm);
  for (int d = 1; d <= kSpikeLengthPx; ++d) {
    const double f = perArm / (1.0 + (d / kSpikeCoreRadiusPx) * (d / kSpikeCoreRadiusPx));
    splat(photons, m_p.width, m_p.height, x + d, y, f);
    splat(photons, m_p.width, m_p.height, x - d, y, f);
    splat(photons, m_p.width, m_p.height, x, y + d, f);
    splat(photons, m_p.width, m_p.height, x, y - d, f);
  }
}

void FrameRenderer::expectedPhotons(int n, std::vector<double>& photons) const {
  photons.assign(static_cast<std::size_t>(m_p.width) * m_p.height, m_p.skyPhotonsPerPxPerFrame);
  const double t = m_s.tOffsetS[n];
  for (std::size_t k = 0; k < m_s.stars.size(); ++k) {
    const auto& star = m_s.stars[k];
    const double x = star.xRefPx + m_p.skyDriftXPxPerS * t;
    const double y = star.yRefPx + m_p.skyDriftYPxPerS * t;
    const int r = star.spikes ? std::max(m_starRadius[k], kSpikeLengthPx + 1) : m_starRadius[k];
    if (x < -r - 1 || y < -r - 1 || x > m_p.width + r || y > m_p.height + r) continue;
    const double spike = star.spikes ? m_p.spikeFraction * star.photonsPerFrame : 0.0;
    m_starStamp.add(photons.data(), m_p.width, m_p.height, x, y, star.photonsPerFrame - spike,
                    m_starRadius[k]);
    if (star.spikes) addSpikes(photons, x, y, spike);
  }
  for (std::size_t k = 0; k < m_s.objects.size(); ++k) {
    const auto& o = m_s.objects[k];
    const double x = o.xRefPx + o.vxPxPerS * t;
    const double y = o.yRefPx + o.vyPxPerS * t;
    const int r = m_objectStamps[k].radiusFor(o.photonsPerFrame, kStampFloorPhotons);
    if (x < -r - 1 || y < -r - 1 || x > m_p.width + r || y > m_p.height + r) continue;
    m_objectStamps[k].add(photons.data(), m_p.width, m_p.height, x, y, o.photonsPerFrame, r);
  }
}

void FrameRenderer::detector(int n, std::vector<double>& photons, Rng& rng, float* out) const {
  const std::size_t count = photons.size();
  const float* flat = m_s.flat.data();
  bool saturated = false;
  for (std::size_t k = 0; k < count; ++k) {
    const double lambda = photons[k] * flat[k];
    const double charge = m_p.noiseless ? lambda : static_cast<double>(poisson(rng, lambda));
    photons[k] = charge;
    saturated = saturated || charge > m_p.fullWellE;
  }
  if (saturated) bleedColumns(photons, m_p.width, m_p.height, m_p.fullWellE);
  const bool em = m_p.emGain > 1.0;
  const double invGain = 1.0 / m_p.gainEPerAdu;
  const double readAdu = m_p.readNoiseE * invGain;
  const float* bias = m_s.bias.data();
  NormalPairs normals;
  for (std::size_t k = 0; k < count; ++k) {
    double e = photons[k];
    if (em) e = m_p.noiseless ? e * m_p.emGain : emRegister(rng, static_cast<std::int64_t>(e), m_p.emGain);
    double adu = bias[k] + e * invGain;
    if (!m_p.noiseless) adu += readAdu * normals.next(rng);
    out[k] = static_cast<float>(adu);
  }
  for (const auto& h : m_s.hot)
    out[static_cast<std::size_t>(h.y) * m_p.width + h.x] += static_cast<float>(h.excessAdu);
  for (const std::size_t c : m_s.cosmicByFrame[n]) {
    const auto& cr = m_s.cosmic[c];
    for (std::size_t k = 0; k < cr.truth.pixels.size(); ++k) {
      const auto [x, y] = cr.truth.pixels[k];
      out[static_cast<std::size_t>(y) * m_p.width + x] += static_cast<float>(cr.amplitudesAdu[k]);
    }
  }
  const float top = static_cast<float>(m_p.saturationAdu);
  for (std::size_t k = 0; k < count; ++k)
    out[k] = std::clamp(out[k], 0.0f, top);
}

void bleedColumns(std::vector<double>& charge, int width, int height, double fullWellE) {
  auto at = [&](int x, int y) -> double& { return charge[static_cast<std::size_t>(y) * width + x]; };
  for (int x = 0; x < width; ++x) {
    for (int y = 0; y < height; ++y) {
      if (at(x, y) <= fullWellE) continue;
      const double excess = at(x, y) - fullWellE;
      at(x, y) = fullWellE;
      double up = 0.5 * excess;
      double down = excess - up;
      for (int yy = y + 1; yy < height && up > 0.0; ++yy) {
        const double room = std::max(0.0, fullWellE - at(x, yy));
        const double put = std::min(room, up);
        at(x, yy) += put;
        up -= put;
      }
      for (int yy = y - 1; yy >= 0 && down > 0.0; --yy) {
        const double room = std::max(0.0, fullWellE - at(x, yy));
        const double put = std::min(room, down);
        at(x, yy) += put;
        down -= put;
      }
    }
  }
}

}  // namespace st::sim::detail

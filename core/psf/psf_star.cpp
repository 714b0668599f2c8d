#include "st/psf/psf_star.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "st/common/env_flag.hpp"
#include "st/common/error.hpp"
#include "st/common/parallel.hpp"
#include "st/stats/order_statistic.hpp"

namespace st::psf {
namespace {

std::string fmt(double v, int digits = 1) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

std::string where(const StarCandidate& c) {
  return "star at (" + fmt(c.x) + ", " + fmt(c.y) + ")";
}

double medianOf(const std::vector<float>& v) {
  return stats::kthSmallest(v.data(), v.size(), v.size() / 2);
}

/// Median and robust sigma of the non-zero finite pixels (subsampled to at most ~2^20).
void robustStats(const Image& image, double* med, double* sigma) {
  const std::size_t stride = std::max<std::size_t>(1, image.size() >> 20);
  // Gathered by chunks on every core (the order does not matter to an order statistic): one thread took
  // ~3 ms of the PSF stage's start on the paper's 1.8M-pixel stack.
  const std::size_t samples = (image.size() + stride - 1) / stride;
  constexpr std::size_t kChunk = std::size_t{1} << 16;
  const std::size_t chunks = (samples + kChunk - 1) / kChunk;
  std::vector<std::vector<float>> parts(chunks);
  parallelFor(chunks, 1, [&](std::size_t c0, std::size_t c1) {
    for (std::size_t c = c0; c < c1; ++c) {
      std::vector<float>& part = parts[c];
      part.reserve(kChunk);
      for (std::size_t k = c * kChunk; k < std::min(samples, (c + 1) * kChunk); ++k) {
        const float p = image.pixels[k * stride];
        if (p != 0.0f && std::isfinite(p)) part.push_back(p);
      }
    }
  });
  std::vector<float> v;
  std::size_t total = 0;
  for (const auto& part : parts)
    total += part.size();
  v.reserve(total);
  for (const auto& part : parts)
    v.insert(v.end(), part.begin(), part.end());
  if (v.size() < 16) {
    *med = 0.0;
    *sigma = 0.0;
    return;
  }
  *med = medianOf(v);
  for (auto& p : v)
    p = std::fabs(p - static_cast<float>(*med));
  *sigma = 1.4826 * medianOf(v);
}

/// Pixels within 3% of the brightest one, within 3 FWHM of the fitted centre. An unsaturated Moffat is above
/// 0.97 of its peak only within r = R sqrt(0.97^(-1/beta) - 1) <= 0.1 FWHM (any beta), so a few pixels at
/// most; the clipped core of a saturated star (in a frame or in a stack) is a plateau of many.
int flatTopPixels(const Image& image, const MoffatFit& fit) {
  const double r = 3.0 * fit.fwhm();
  const int x0 = std::max(0, int(std::floor(fit.x0 - r))), x1 = std::min(image.width - 1, int(fit.x0 + r));
  const int y0 = std::max(0, int(std::floor(fit.y0 - r))), y1 = std::min(image.height - 1, int(fit.y0 + r));
  float top = -std::numeric_limits<float>::infinity();
  for (int y = y0; y <= y1; ++y)
    for (int x = x0; x <= x1; ++x)
      top = std::max(top, image.at(x, y));
  const double level = fit.background + 0.97 * (top - fit.background);
  int count = 0;
  for (int y = y0; y <= y1; ++y)
    for (int x = x0; x <= x1; ++x)
      count += image.at(x, y) >= level ? 1 : 0;
  return count;
}

/// Why a fit is not acceptable as the PSF, or empty when it is.
std::string judgeFit(const Image& image, const MoffatFit& fit, const StarCandidate& c, double noise,
                     const PsfStarOptions& o) {
  if (!fit.converged()) return where(c) + ": " + toString(fit.convergence);
  if (betaAtFitBound(fit.model.beta))
    return where(c) + ": beta " + fmt(fit.model.beta, 2) + " at the fit's bound (not a Moffat profile)";
  const double w = fit.fwhm();
  const int flat = flatTopPixels(image, fit);
  const double flatLimit = std::max(8.0, M_PI * std::pow(0.1 * w + 1.0, 2));
  if (flat > flatLimit)
    return where(c) + ": flat-topped core (" + std::to_string(flat) + " px within 3% of the peak; saturated)";
  if (!(w >= o.minFwhmPx && w <= o.maxFwhmPx))
    return where(c) + ": FWHM " + fmt(w, 2) + " px outside [" + fmt(o.minFwhmPx) + ", " + fmt(o.maxFwhmPx) +
           "]";
  if (std::hypot(fit.x0 - c.x, fit.y0 - c.y) > fitWanderLimitPx(w))
    return where(c) + ": fit wandered to (" + fmt(fit.x0) + ", " + fmt(fit.y0) + ")";
  if (noise > 0.0 && fit.amplitude / noise < o.minPeakSnr)
    return where(c) + ": peak SNR " + fmt(fit.amplitude / noise) + " below " + fmt(o.minPeakSnr);
  if (fit.amplitude <= 0.0) return where(c) + ": non-positive amplitude";
  return {};
}

/// Which of the accepted fits (brightest first) gives the PSF: the brightest, unless three or more were
/// accepted, when it is the brightest whose FWHM is within max(3 sigma, 2%) of their median (a star blended
/// with a faint neighbour, or left with a residual by earlier stages, does not set the PSF), or else the
/// median one.
std::size_t chooseAccepted(const std::vector<std::pair<MoffatFit, StarCandidate>>& accepted) {
  if (accepted.size() < 3) return 0;
  std::vector<std::size_t> order(accepted.size());
  for (std::size_t i = 0; i < order.size(); ++i)
    order[i] = i;
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return accepted[a].first.fwhm() < accepted[b].first.fwhm();
  });
  const std::size_t median = order[(order.size() - 1) / 2];
  const double mid = accepted[median].first.fwhm();
  for (std::size_t i = 0; i < accepted.size(); ++i) {
    const MoffatFit& f = accepted[i].first;
    if (std::fabs(f.fwhm() - mid) <= std::max(3.0 * f.sigmaFwhm, 0.02 * mid)) return i;
  }
  return median;
}

}  // namespace

double robustImageNoise(const Image& image) {
  double med = 0.0, sigma = 0.0;
  robustStats(image, &med, &sigma);
  return sigma;
}

std::vector<StarCandidate> findStarCandidates(const Image& image, double thresholdSigma,
                                              std::optional<double> saturationLevel) {
  double med = 0.0, sigma = 0.0;
  robustStats(image, &med, &sigma);
  const double threshold = med + thresholdSigma * sigma;
  std::vector<StarCandidate> out;
  for (int y = 1; y + 1 < image.height; ++y)
    for (int x = 1; x + 1 < image.width; ++x) {
      const float v = image.at(x, y);
      if (!(v > threshold)) continue;
      bool isMax = true;
      int equal = 1;
      for (int dy = -1; dy <= 1 && isMax; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          if (dx == 0 && dy == 0) continue;
          const float n = image.at(x + dx, y + dy);
          const bool before = dy < 0 || (dy == 0 && dx < 0);
          if (n > v || (before && n == v)) {
            isMax = false;
            break;
          }
          equal += (n == v) ? 1 : 0;
        }
      if (!isMax) continue;
      StarCandidate c{double(x), double(y), 0.0, false};
      for (int dy = -2; dy <= 2; ++dy)
        for (int dx = -2; dx <= 2; ++dx)
          if (image.contains(x + dx, y + dy)) c.flux += image.at(x + dx, y + dy) - med;
      c.saturated = equal >= 3 || (saturationLevel && v >= *saturationLevel);
      out.push_back(c);
    }
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.flux > b.flux; });
  return out;
}

PsfMeasurement measurePsf(const Image& image, const std::vector<StarCandidate>& given,
                          const PsfStarOptions& o) {
  const std::vector<StarCandidate> all =
      given.empty() ? findStarCandidates(image, 10.0, o.saturationLevel) : given;
  std::vector<StarCandidate> sorted = all;
  std::sort(sorted.begin(), sorted.end(), [](const auto& a, const auto& b) { return a.flux > b.flux; });
  const double noise = o.imageNoise ? *o.imageNoise : robustImageNoise(image);
  PsfMeasurement m;
  std::vector<std::pair<MoffatFit, StarCandidate>> accepted;
  // The candidates that pass the cuts, brightest first, up to maxTries (the cuts do not depend on the fits).
  std::vector<const StarCandidate*> eligible;
  for (const auto& c : sorted) {
    if (static_cast<int>(eligible.size()) >= o.maxTries) break;
    if (c.saturated || !(c.flux > 0.0)) continue;
    const int margin = std::min(o.edgeMarginPx, std::min(image.width, image.height) / 8);
    if (c.x < margin || c.y < margin || c.x > image.width - 1 - margin || c.y > image.height - 1 - margin)
      continue;
    if (o.saturationLevel && image.at(int(std::lround(c.x)), int(std::lround(c.y))) >= *o.saturationLevel)
      continue;
    const double isoR = o.isolationRadiusPx;
    const bool crowded = std::any_of(all.begin(), all.end(), [&](const StarCandidate& n) {
      const double d = std::hypot(n.x - c.x, n.y - c.y);
      return d > 0.5 && d < isoR && (n.saturated || n.flux > o.isolationFluxRatio * c.flux);
    });
    if (crowded) continue;
    eligible.push_back(&c);
  }
  // Fitted in waves, brightest first, until maxAccepted are accepted: each wave fits as many candidates as
  // are still needed (9 in a whole wave where all pass, as on the paper's stack), the whole fits in parallel
  // and each fit's model on every core (fitMoffat: the pixels in parallel, summed in order; the calls nest),
  // then judges them in order. No fit runs past the stop, and the fits and the choice are those of one fit
  // at a time. One at a time, the 9 fits took 47 ms on the paper's stack with 16 threads, at 8 cores (issue
  // 16, 2026-12-03); batches of 16 whole fits fitted up to 7 stars past the stop and waited for the slowest
  // (~100 ms).
  // A fit far below minPeakSnr is not refined with the smear (MoffatFitOptions::rejectBelowAmplitude): it is
  // rejected all the same.
  MoffatFitOptions fitOptions = o.fit;
  if (noise > 0.0 && o.minPeakSnr > 0.0) fitOptions.rejectBelowAmplitude = o.minPeakSnr * noise;
  const std::size_t wanted = static_cast<std::size_t>(std::max(1, o.maxAccepted));
  // Benchmark knob: ST_PSF_FITS_ONE_AT_A_TIME=1 fits one star a wave (the fits of before, for figures).
  static const bool oneAtATime = envFlag("ST_PSF_FITS_ONE_AT_A_TIME");
  for (std::size_t next = 0; next < eligible.size() && accepted.size() < wanted;) {
    const std::size_t wave = oneAtATime ? 1 : std::min(eligible.size() - next, wanted - accepted.size());
    std::vector<std::optional<MoffatFit>> fits(wave);
    std::vector<std::string> failed(wave);
    parallelFor(wave, 1, [&](std::size_t i0, std::size_t i1) {
      for (std::size_t i = i0; i < i1; ++i) {
        const StarCandidate& c = *eligible[next + i];
        try {
          fits[i] = fitMoffat(image, c.x, c.y, fitOptions);
        } catch (const InputError& e) {
          failed[i] = where(c) + ": " + e.what();
        }
      }
    });
    for (std::size_t i = 0; i < wave && accepted.size() < wanted; ++i) {
      const StarCandidate& c = *eligible[next + i];
      ++m.candidatesConsidered;
      if (!fits[i]) {
        m.rejected.push_back(failed[i]);
        continue;
      }
      const std::string why = judgeFit(image, *fits[i], c, noise, o);
      if (!why.empty()) {
        m.rejected.push_back(why);
        continue;
      }
      accepted.emplace_back(*fits[i], c);
    }
    next += wave;
  }
  if (!accepted.empty()) {
    const std::size_t pick = chooseAccepted(accepted);
    for (const auto& a : accepted)
      m.acceptedFwhm.push_back(a.first.fwhm());
    std::sort(m.acceptedFwhm.begin(), m.acceptedFwhm.end());
    m.fit = accepted[pick].first;
    m.star = accepted[pick].second;
    return m;
  }
  std::string msg =
      "no star usable for the PSF among " + std::to_string(all.size()) +
      " candidates (need a bright, isolated, unsaturated star away from the edges); give the PSF "
      "FWHM instead (e.g. --fwhm)";
  for (std::size_t i = 0; i < std::min<std::size_t>(3, m.rejected.size()); ++i)
    msg += "; " + m.rejected[i];
  throw InputError(msg);
}

PsfMeasurement measurePsfAt(const Image& image, double x, double y, const PsfStarOptions& o) {
  PsfMeasurement m;
  m.star = {x, y, 0.0, false};
  m.fit = fitMoffat(image, x, y, o.fit);
  m.candidatesConsidered = 1;
  const std::string why = judgeFit(image, m.fit, m.star, robustImageNoise(image), o);
  if (!why.empty())
    throw InputError("PSF fit on the given " + why + "; give the PSF FWHM instead (e.g. --fwhm)");
  return m;
}

}  // namespace st::psf

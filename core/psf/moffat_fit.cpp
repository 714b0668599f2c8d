#include "st/psf/moffat_fit.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "moffat_samples.hpp"
#include "st/common/error.hpp"
#include "st/common/parallel.hpp"
#include "st/common/trace.hpp"

namespace st::psf {
namespace {

using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat6 = Eigen::Matrix<double, 6, 6>;
using detail::kAmp, detail::kBeta, detail::kBg, detail::kR, detail::kX0, detail::kY0;

constexpr double kMinRadius = 0.2;
constexpr double kMaxRadius = 200.0;
constexpr double kMinBeta = kFitMinBeta;
constexpr double kMaxBeta = kFitMaxBeta;

struct Pixel {
  double x, y, value;
};

/// Per-pixel residuals and model gradients of one evaluation, reused across the evaluations of a fit.
struct Workspace {
  std::vector<double> residual;
  std::vector<Vec6> grad;
};

/// Model samples (pixels x smear offsets x Gauss points) per parallel chunk: ~50-100 us of exp and log
/// (detail::moffatModelAt: ~5 ns a sample on one core of the 2-core VM), so a chunk outweighs its hand-over;
/// a plain fit's 35 x 35 stamp (16 samples a pixel) still splits in two.
constexpr std::size_t kSamplesPerChunk = 16384;

/// The model's samples of a pixel (detail::MoffatSamples) and, for ST_PSF_LIBM_MODEL=1, its rule and smear.
struct Model {
  Moffat::GaussRule rule;
  SmearKernel smear;
  detail::MoffatSamples samples;
  Model(const Moffat::GaussRule& g, const SmearKernel& k)
      : rule(g), smear(k), samples(detail::moffatSamples(g, k)) {}
};

/// Sum of squared residuals; with normal equations when jtj/jtr are given. The pixels' models are computed on
/// every core (a smeared model is K x 16 exp and log per pixel), then summed in pixel order on this thread:
/// the same sums, bit for bit, as one pixel at a time.
double evaluate(const std::vector<Pixel>& pixels, const Vec6& p, const Model& m, Mat6* jtj, Vec6* jtr,
                Workspace& ws) {
  const std::size_t n = pixels.size();
  ws.residual.resize(n);
  if (jtj) ws.grad.resize(n);
  const std::size_t samples = m.samples.weight.size();
  // The lanes' model where the CPU runs them as AVX2; elsewhere their scalar form is ~1.4x slower than the
  // C library's exp and log, and the model of before is kept (the fitted parameters differ by ~1e-15).
  const bool libm = detail::moffatModelLibm() || !detail::moffatLanesAvx2();
  parallelFor(n, std::max<std::size_t>(1, kSamplesPerChunk / std::max<std::size_t>(1, samples)),
              [&](std::size_t i0, std::size_t i1) {
                for (std::size_t i = i0; i < i1; ++i) {
                  double* grad = jtj ? ws.grad[i].data() : nullptr;
                  const double model =
                      libm ? detail::moffatModelAtLibm(p.data(), pixels[i].x, pixels[i].y, m.rule, m.smear,
                                                       grad)
                           : detail::moffatModelAt(p.data(), pixels[i].x, pixels[i].y, m.samples, grad);
                  ws.residual[i] = pixels[i].value - model;
                }
              });
  double ssr = 0.0;
  if (jtj) jtj->setZero();
  if (jtr) jtr->setZero();
  for (std::size_t i = 0; i < n; ++i) {
    const double r = ws.residual[i];
    ssr += r * r;
    if (jtj) {
      jtj->selfadjointView<Eigen::Lower>().rankUpdate(ws.grad[i]);
      *jtr += ws.grad[i] * r;
    }
  }
  if (jtj) *jtj = jtj->selfadjointView<Eigen::Lower>();
  return ssr;
}

void clampParams(Vec6& p) {
  p[kR] = std::clamp(p[kR], kMinRadius, kMaxRadius);
  p[kBeta] = std::clamp(p[kBeta], kMinBeta, kMaxBeta);
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

struct Stamp {
  int x0, y0, x1, y1;  // inclusive-exclusive bounds
};

Stamp clipStamp(const Image& image, int cx, int cy, int half) {
  return {std::max(0, cx - half), std::max(0, cy - half), std::min(image.width, cx + half + 1),
          std::min(image.height, cy + half + 1)};
}

/// Starting values: brightest pixel near the guess, border median as background, FWHM from the area above
/// half maximum. Returns the parameters and the FWHM estimate.
Vec6 initialGuess(const Image& image, double xg, double yg, const MoffatFitOptions& o, double* fwhmGuess) {
  int bx = static_cast<int>(std::lround(xg)), by = static_cast<int>(std::lround(yg));
  float best = image.at(bx, by);
  for (int y = std::max(0, by - 2); y <= std::min(image.height - 1, by + 2); ++y)
    for (int x = std::max(0, bx - 2); x <= std::min(image.width - 1, bx + 2); ++x)
      if (image.at(x, y) > best) best = image.at(x, y), bx = x, by = y;
  const int half = o.halfSize > 0 ? o.halfSize : 12;
  const Stamp st = clipStamp(image, bx, by, half);
  std::vector<double> border;
  for (int y = st.y0; y < st.y1; ++y)
    for (int x = st.x0; x < st.x1; ++x) {
      const bool edge = y == st.y0 || y == st.y1 - 1 || x == st.x0 || x == st.x1 - 1;
      if (edge && !(o.ignoreZeros && image.at(x, y) == 0.0f)) border.push_back(image.at(x, y));
    }
  const double bg = median(border);
  const double amp = std::max(1e-30, double(best) - bg);
  int above = 0;
  for (int y = st.y0; y < st.y1; ++y)
    for (int x = st.x0; x < st.x1; ++x)
      above += (image.at(x, y) - bg > 0.5 * amp) ? 1 : 0;
  *fwhmGuess = std::max(1.0, 2.0 * std::sqrt(above / M_PI));
  Vec6 p;
  p << bx, by, Moffat::radiusForFwhm(*fwhmGuess, o.betaGuess), o.betaGuess, amp, bg;
  return p;
}

/// The state of a Levenberg-Marquardt run: parameters, sum of squared residuals, J^T J at the end.
struct LmState {
  Vec6 p;
  double ssr = 0.0;
  Mat6 jtj;
  int iterations = 0;
  FitConvergence convergence = FitConvergence::MaxIterations;
  [[nodiscard]] bool converged() const noexcept {
    return convergence != FitConvergence::MaxIterations && convergence != FitConvergence::Diverged;
  }
};

/// Levenberg-Marquardt from `start` (damping on the diagonal of J^T J, x10 / x0.1).
LmState runLevenbergMarquardt(const std::vector<Pixel>& pixels, const Vec6& start, const Model& model,
                              int maxIterations) {
  LmState st;
  Vec6 p = start;
  Mat6 jtj, trialJtj;
  Vec6 jtr, trialJtr;
  Workspace ws, trialWs;
  double ssr = evaluate(pixels, p, model, &jtj, &jtr, ws);
  double lambda = 1e-3;
  int it = 0;
  FitConvergence conv = FitConvergence::MaxIterations;
  for (; it < maxIterations; ++it) {
    if (jtr.cwiseAbs().maxCoeff() <= 1e-12 * (ssr + 1e-300)) {
      conv = FitConvergence::SmallGradient;
      break;
    }
    bool accepted = false;
    while (!accepted) {
      Mat6 a = jtj;
      a.diagonal() += lambda * jtj.diagonal().cwiseMax(1e-12);
      Vec6 trial = p + a.ldlt().solve(jtr);
      clampParams(trial);
      // With its normal equations: moffatModelAt computes the gradient's sums with the value either way, so
      // they cost a rank update per pixel, and an accepted trial is not evaluated again (half the exp and log
      // of a fit; the same sums bit for bit, as moffatModelAt's value does not depend on whether the gradient
      // is kept).
      const double trialSsr = evaluate(pixels, trial, model, &trialJtj, &trialJtr, trialWs);
      if (std::isfinite(trialSsr) && trialSsr < ssr) {
        const double step = ((trial - p).cwiseAbs().array() / (p.cwiseAbs().array() + 1e-12)).maxCoeff();
        const double reduction = (ssr - trialSsr) / std::max(ssr, 1e-300);
        p = trial;
        ssr = trialSsr;
        jtj = trialJtj;
        jtr = trialJtr;
        lambda = std::max(lambda * 0.1, 1e-12);
        accepted = true;
        if (reduction < 1e-10) conv = FitConvergence::RelativeReduction;
        if (step < 1e-9) conv = FitConvergence::SmallStep;
      } else {
        lambda *= 10.0;
        if (lambda > 1e12) {
          // No step helps: at a minimum when the last relative change was already tiny.
          const bool atMinimum = std::isfinite(trialSsr) && (trialSsr - ssr) <= 1e-10 * ssr;
          conv = atMinimum ? FitConvergence::RelativeReduction : FitConvergence::Diverged;
          break;
        }
      }
    }
    if (conv != FitConvergence::MaxIterations) break;
  }
  st.p = p;
  st.ssr = ssr;
  st.jtj = jtj;
  st.iterations = it + 1;
  st.convergence = conv;
  return st;
}

double fwhmDerivBeta(double r, double beta) {
  const double t = std::pow(2.0, 1.0 / beta);
  return 2.0 * r * (0.5 / std::sqrt(t - 1.0)) * t * std::log(2.0) * (-1.0 / (beta * beta));
}

}  // namespace

std::string toString(FitConvergence c) {
  switch (c) {
    case FitConvergence::RelativeReduction:
      return "converged (relative chi^2 reduction < 1e-10)";
    case FitConvergence::SmallStep:
      return "converged (relative step < 1e-9)";
    case FitConvergence::SmallGradient:
      return "converged (gradient below tolerance)";
    case FitConvergence::MaxIterations:
      return "not converged (iteration limit reached)";
    case FitConvergence::Diverged:
      return "not converged (no step reduces chi^2)";
  }
  return "unknown";
}

MoffatFit fitMoffat(const Image& image, double xGuess, double yGuess, const MoffatFitOptions& o) {
  if (!std::isfinite(xGuess) || !std::isfinite(yGuess) ||
      !image.contains(int(std::lround(xGuess)), int(std::lround(yGuess))))
    throw InputError("Moffat fit: star position (" + std::to_string(xGuess) + ", " + std::to_string(yGuess) +
                     ") is outside the " + std::to_string(image.width) + " x " +
                     std::to_string(image.height) + " image");
  const Moffat::GaussRule s = Moffat::gaussRule(o.subsamples);
  if (o.smear.dx.size() != o.smear.weight.size() || o.smear.dy.size() != o.smear.weight.size())
    throw InputError("Moffat fit: smear kernel has " + std::to_string(o.smear.dx.size()) + " x offsets, " +
                     std::to_string(o.smear.dy.size()) + " y offsets and " +
                     std::to_string(o.smear.weight.size()) + " weights; they must match");
  double fwhmGuess = 0.0;
  Vec6 p = initialGuess(image, xGuess, yGuess, o, &fwhmGuess);
  const int half = o.halfSize > 0 ? o.halfSize : std::clamp(int(std::ceil(4.0 * fwhmGuess)), 6, 30);
  const Stamp st = clipStamp(image, int(p[kX0]), int(p[kY0]), half);
  std::vector<Pixel> pixels;
  for (int y = st.y0; y < st.y1; ++y)
    for (int x = st.x0; x < st.x1; ++x) {
      const float v = image.at(x, y);
      if (!std::isfinite(v) || (o.ignoreZeros && v == 0.0f)) continue;
      pixels.push_back({double(x), double(y), double(v)});
    }
  if (pixels.size() < 20)
    throw InputError("Moffat fit: only " + std::to_string(pixels.size()) + " usable pixels around (" +
                     std::to_string(xGuess) + ", " + std::to_string(yGuess) + "); need at least 20");

  // Without a smear kernel first (cheap), then from there with it: the smeared model costs K times more per
  // pixel and only moves R and beta by a few per cent, and the centre by a fraction of a pixel. A plain fit
  // pinned at a beta bound whose centre also left its star (farther than 2 px beyond fitWanderLimitPx,
  // measurePsf's limit) is no star's profile: a bright blend, a saturated core (R 113 px, beta 50, 35 px from
  // its guess on paper-neo's 300-frame stack). Refining it ran to the iteration limit on the widest stamp,
  // 200 x 3721 pixels x K x 16 exp and log, 3-7 s of the 2-core machine's pre-processing, for a fit rejected
  // all the same. A pinned fit near its star is refined: a trail the plain model cannot follow may pin beta
  // until the smear is modelled.
  const SmearKernel none{{0.0}, {0.0}, {1.0}};
  auto t0 = trace::Clock::now();
  LmState lm = runLevenbergMarquardt(pixels, p, Model(s, none), o.maxIterations);
  if (trace::enabled())
    trace::record("Moffat fit: plain, " + std::to_string(pixels.size()) + " pixels, " +
                      std::to_string(lm.iterations) + " iterations",
                  t0, trace::Clock::now());
  const double plainFwhm = Moffat{lm.p[kR], lm.p[kBeta]}.fwhm();
  const bool strayed = betaAtFitBound(lm.p[kBeta]) && !(std::hypot(lm.p[kX0] - xGuess, lm.p[kY0] - yGuess) <=
                                                        fitWanderLimitPx(plainFwhm) + 2.0);
  // Nor is a plain fit too faint for the caller by a factor of two, once the smear's loss of peak is put
  // back (the smeared model's amplitude is the PSF's peak, above the stack's): on paper-neo's 100-frame stack
  // measurePsf fits 30 candidates for 5 acceptable ones, and the smeared refinements of the 21 with peak SNR
  // 2-12 (against its 20, on stamps up to 61 x 61 px as their plain FWHM is wide) took ~3.5 of the stage's
  // ~4 s on the 2-core machine (2026-12-02).
  // The PSF under the smear is estimated by second moments: the plain fit's per-axis variance (a Moffat's
  // R^2 / (2 (beta - 2)), beta > 2) less the smear's mean per-axis variance; with none left (a smear as wide
  // as the star) or beta <= 2 the fit is refined as before. The plain profile alone, already widened by the
  // smear, would understate the loss for trails longer than the star.
  bool tooFaint = false;
  if (o.rejectBelowAmplitude > 0.0 && !o.smear.empty() && lm.converged() && lm.p[kBeta] > 2.0) {
    const SmearKernel& k = o.smear;
    double mx = 0.0, my = 0.0;
    for (std::size_t i = 0; i < k.weight.size(); ++i)
      mx += k.weight[i] * k.dx[i], my += k.weight[i] * k.dy[i];
    double vx = 0.0, vy = 0.0;
    for (std::size_t i = 0; i < k.weight.size(); ++i) {
      vx += k.weight[i] * (k.dx[i] - mx) * (k.dx[i] - mx);
      vy += k.weight[i] * (k.dy[i] - my) * (k.dy[i] - my);
    }
    const double beta = lm.p[kBeta];
    const double psfVariance = lm.p[kR] * lm.p[kR] / (2.0 * (beta - 2.0)) - 0.5 * (vx + vy);
    if (psfVariance > 0.0) {
      const Moffat psf{std::sqrt(2.0 * (beta - 2.0) * psfVariance), beta};
      double peak = 0.0;  // the smeared PSF's peak, at the smear's centroid, over the PSF's
      for (std::size_t i = 0; i < k.weight.size(); ++i)
        peak += k.weight[i] * psf(k.dx[i] - mx, k.dy[i] - my);
      tooFaint = peak > 0.0 && lm.p[kAmp] / peak < 0.5 * o.rejectBelowAmplitude;
    }
  }
  if (!o.smear.empty() && lm.converged() && !strayed && !tooFaint) {
    const int used = lm.iterations;
    t0 = trace::Clock::now();
    lm = runLevenbergMarquardt(pixels, lm.p, Model(s, o.smear), o.maxIterations);
    if (trace::enabled())
      trace::record("Moffat fit: with the smear, " + std::to_string(o.smear.weight.size()) + " offsets, " +
                        std::to_string(lm.iterations) + " iterations",
                    t0, trace::Clock::now());
    lm.iterations += used;
  }
  p = lm.p;
  const double ssr = lm.ssr;
  const Mat6& jtj = lm.jtj;
  MoffatFit fit;
  fit.convergence = lm.convergence;
  fit.iterations = lm.iterations;
  fit.x0 = p[kX0];
  fit.y0 = p[kY0];
  fit.model = Moffat{p[kR], p[kBeta]};
  fit.amplitude = p[kAmp];
  fit.background = p[kBg];
  fit.pixels = static_cast<int>(pixels.size());
  const double dof = std::max<double>(1.0, double(pixels.size()) - 6.0);
  fit.residualRms = std::sqrt(ssr / double(pixels.size()));
  const double variance = o.noiseSigma > 0.0 ? o.noiseSigma * o.noiseSigma : ssr / dof;
  fit.reducedChi2 = o.noiseSigma > 0.0 ? ssr / dof / variance : 1.0;
  const Mat6 cov = jtj.ldlt().solve(Mat6::Identity()) * variance;
  fit.sigmaX0 = std::sqrt(std::max(0.0, cov(kX0, kX0)));
  fit.sigmaY0 = std::sqrt(std::max(0.0, cov(kY0, kY0)));
  fit.sigmaRadius = std::sqrt(std::max(0.0, cov(kR, kR)));
  fit.sigmaBeta = std::sqrt(std::max(0.0, cov(kBeta, kBeta)));
  fit.sigmaAmplitude = std::sqrt(std::max(0.0, cov(kAmp, kAmp)));
  fit.sigmaBackground = std::sqrt(std::max(0.0, cov(kBg, kBg)));
  const double dWdR = fit.model.fwhm() / p[kR], dWdB = fwhmDerivBeta(p[kR], p[kBeta]);
  fit.sigmaFwhm = std::sqrt(std::max(
      0.0, dWdR * dWdR * cov(kR, kR) + dWdB * dWdB * cov(kBeta, kBeta) + 2.0 * dWdR * dWdB * cov(kR, kBeta)));
  return fit;
}

std::vector<RadialBin> radialProfile(const Image& image, const MoffatFit& fit, double maxRadius,
                                     double binWidth, int subsamples) {
  if (!(binWidth > 0.0) || !(maxRadius > 0.0))
    throw InputError("radial profile: bin width (" + std::to_string(binWidth) + ") and maximum radius (" +
                     std::to_string(maxRadius) + ") must be positive");
  const int nBins = static_cast<int>(std::ceil(maxRadius / binWidth));
  std::vector<RadialBin> bins(static_cast<std::size_t>(nBins));
  const int x0 = std::max(0, int(std::floor(fit.x0 - maxRadius))),
            x1 = std::min(image.width - 1, int(std::ceil(fit.x0 + maxRadius)));
  const int y0 = std::max(0, int(std::floor(fit.y0 - maxRadius))),
            y1 = std::min(image.height - 1, int(std::ceil(fit.y0 + maxRadius)));
  for (int y = y0; y <= y1; ++y)
    for (int x = x0; x <= x1; ++x) {
      const float v = image.at(x, y);
      const double r = std::hypot(x - fit.x0, y - fit.y0);
      if (r >= maxRadius || v == 0.0f || !std::isfinite(v)) continue;
      auto& b = bins[static_cast<std::size_t>(r / binWidth)];
      b.radius += r;
      b.mean += v - fit.background;
      b.model += fit.amplitude * fit.model.pixelMean(x - fit.x0, y - fit.y0, subsamples);
      ++b.count;
    }
  std::vector<RadialBin> out;
  for (auto& b : bins) {
    if (b.count == 0) continue;
    b.radius /= b.count;
    b.mean /= b.count;
    b.model /= b.count;
    out.push_back(b);
  }
  return out;
}

std::string implausibleFit(const MoffatFit& fit, double xGuess, double yGuess, int width, int height) {
  char buf[160];
  const double w = fit.fwhm();
  if (!std::isfinite(fit.x0) || !std::isfinite(fit.y0) || !std::isfinite(w))
    return "non-finite centre or FWHM";
  if (fit.x0 < -0.5 || fit.y0 < -0.5 || fit.x0 > width - 0.5 || fit.y0 > height - 0.5) {
    std::snprintf(buf, sizeof buf, "centre (%.1f, %.1f) outside the image", fit.x0, fit.y0);
    return buf;
  }
  const double d = std::hypot(fit.x0 - xGuess, fit.y0 - yGuess);
  if (d > std::max(5.0, 2.0 * w)) {
    std::snprintf(buf, sizeof buf, "centre %.1f px from the point clicked", d);
    return buf;
  }
  if (w < 0.5) {
    std::snprintf(buf, sizeof buf, "FWHM %.2f px is narrower than a pixel", w);
    return buf;
  }
  if (w > 0.25 * std::min(width, height)) {
    std::snprintf(buf, sizeof buf, "FWHM %.1f px is wider than a quarter of the image", w);
    return buf;
  }
  if (fit.model.beta >= 40.0) {
    std::snprintf(buf, sizeof buf, "beta %.1f at its bound (no wings)", fit.model.beta);
    return buf;
  }
  return {};
}

}  // namespace st::psf

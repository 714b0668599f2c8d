#include "st/fit/montecarlo.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "st/fit/comoving_fit.hpp"
#include "st/fit/pixel_psf.hpp"
#include "st/fit/uncertainty.hpp"

namespace st::fit {

void renderMovingSource(FrameCube& cube, const psf::Moffat& psf, const MovingSource& source) {
  constexpr int kSub = 5;
  const double alpha = source.photons / psf.integral();
  const int reach = static_cast<int>(std::ceil(4.0 * psf.fwhm())) + 4;
  const std::vector<double> t = cube.timeOffsetsS();
  for (std::size_t n = 0; n < cube.frameCount(); ++n) {
    const double sx = source.x + source.v.vx * t[n];
    const double sy = source.y + source.v.vy * t[n];
    const int x0 = std::max(0, static_cast<int>(std::floor(sx)) - reach);
    const int x1 = std::min(cube.width() - 1, static_cast<int>(std::ceil(sx)) + reach);
    const int y0 = std::max(0, static_cast<int>(std::floor(sy)) - reach);
    const int y1 = std::min(cube.height() - 1, static_cast<int>(std::ceil(sy)) + reach);
    float* img = cube.frame(n);
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        double sum = 0.0;
        for (int j = 0; j < kSub; ++j) {
          for (int i = 0; i < kSub; ++i) {
            sum += psf(x + (i + 0.5) / kSub - 0.5 - sx, y + (j + 0.5) / kSub - 0.5 - sy);
          }
        }
        img[static_cast<std::size_t>(y) * cube.width() + x] +=
            static_cast<float>(alpha * sum / (kSub * kSub));
      }
    }
  }
}

FrameCube makeEmptyCube(int size, int frames, double cadenceS) {
  FrameCube cube(size, size, static_cast<std::size_t>(frames));
  for (int n = 0; n < frames; ++n) {
    cube.info()[n].mjdMid = 60000.0 + n * cadenceS / kSecondsPerDay;
    cube.info()[n].exposureS = cadenceS;
  }
  return cube;
}

void addNoise(FrameCube& cube, double sigmaN, bool photonNoise, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  for (float& v : cube.pixels()) {
    double value = v;
    if (photonNoise) {
      value = v > 0.0f ? static_cast<double>(std::poisson_distribution<long>(v)(rng)) : 0.0;
    }
    v = static_cast<float>(value + sigmaN * gauss(rng));
  }
}

namespace {

double stdDev(const std::vector<double>& v, double& mean) {
  mean = 0.0;
  for (double x : v)
    mean += x;
  mean /= static_cast<double>(v.size());
  double s = 0.0;
  for (double x : v)
    s += (x - mean) * (x - mean);
  return v.size() > 1 ? std::sqrt(s / static_cast<double>(v.size() - 1)) : 0.0;
}

}  // namespace

MonteCarloPoint runMonteCarlo(const MonteCarloConfig& c, CancelToken& cancel) {
  MonteCarloPoint out;
  out.config = c;
  std::mt19937_64 rng(c.seed);
  std::uniform_real_distribution<double> jitter(-0.5, 0.5);
  FitOptions opt;
  opt.psf = c.psf;
  opt.stampHalfSize = c.stampHalfSize;
  opt.sigmaN = c.sigmaN;
  const FrameCube empty = makeEmptyCube(c.size, c.frames, c.cadenceS);
  const double span = std::max(empty.timeSpanS(), 1e-9);
  std::vector<double> dx, dy, dvx, dvy;
  double snrSum = 0.0, photonSum = 0.0, hessSum = 0.0;
  for (int trial = 0; trial < c.trials; ++trial) {
    cancel.throwIfCancelled();
    MovingSource src{0.5 * c.size + jitter(rng), 0.5 * c.size + jitter(rng), c.v, c.photonsPerFrame};
    FrameCube cube = empty;
    renderMovingSource(cube, c.psf, src);
    addNoise(cube, c.sigmaN, c.photonNoise, rng());
    FitParams start;
    start.xc = std::round(src.x);
    start.yc = std::round(src.y);
    start.v = {c.v.vx + 0.2 / span, c.v.vy - 0.2 / span};
    start.alpha = std::numeric_limits<double>::quiet_NaN();
    const FitResult r = fitComoving(cube, start, opt);
    if (!r.ok()) continue;
    dx.push_back(r.params.xc - src.x);
    dy.push_back(r.params.yc - src.y);
    dvx.push_back(r.params.v.vx - c.v.vx);
    dvy.push_back(r.params.v.vy - c.v.vy);
    snrSum += r.snr;
    photonSum += r.photonsPerFrame;
    hessSum += 0.5 * (r.sigma[kXc] + r.sigma[kYc]);
  }
  out.converged = static_cast<int>(dx.size());
  if (out.converged > 1) {
    out.sdX = stdDev(dx, out.meanDx);
    out.sdY = stdDev(dy, out.meanDy);
    out.sdVx = stdDev(dvx, out.meanDvx);
    out.sdVy = stdDev(dvy, out.meanDvy);
    out.sdPos = std::sqrt(0.5 * (out.sdX * out.sdX + out.sdY * out.sdY));
    out.sdVel = std::sqrt(0.5 * (out.sdVx * out.sdVx + out.sdVy * out.sdVy));
    out.meanSnr = snrSum / out.converged;
    out.meanPhotons = photonSum / out.converged;
    out.meanHessianSigmaPos = hessSum / out.converged;
  }
  const double w = c.psf.fwhm();
  out.predictedSigmaPos = positionSigmaPaper(c.photonsPerFrame, w, c.sigmaN, c.frames);
  out.predictedSigmaVel = velocitySigma(out.predictedSigmaPos, effectiveDurationS(empty.timeOffsetsS()));
  out.predictedSnr =
      detectionSnr(c.photonsPerFrame / c.psf.integral(), c.frames, pixelPsfSumOfSquares(c.psf), c.sigmaN);
  return out;
}

}  // namespace st::fit

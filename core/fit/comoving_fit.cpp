#include "st/fit/comoving_fit.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <sstream>

#include "fit_problem.hpp"
#include "st/common/error.hpp"
#include "st/fit/pixel_psf.hpp"
#include "st/fit/uncertainty.hpp"

namespace st::fit {

ParamVector FitParams::toVector() const {
  ParamVector p;
  p << v.vx, v.vy, xc, yc, alpha, i0;
  return p;
}

FitParams FitParams::fromVector(const ParamVector& p) {
  FitParams f;
  f.v = {p[kVx], p[kVy]};
  f.xc = p[kXc];
  f.yc = p[kYc];
  f.alpha = p[kAlpha];
  f.i0 = p[kI0];
  return f;
}

double lowSnrVarianceFactor(double snr) noexcept {
  if (!(snr > 0.0) || !std::isfinite(snr)) return 1.0;
  return 1.0 + kLowSnrVarianceCoefficient / (snr * snr);
}

FitParams startFromCandidate(const search::Candidate& candidate) {
  FitParams p;
  p.v = candidate.v;
  p.xc = candidate.x;
  p.yc = candidate.y;
  p.alpha = std::numeric_limits<double>::quiet_NaN();
  p.i0 = 0.0;
  return p;
}

const char* toString(FitStatus status) noexcept {
  switch (status) {
    case FitStatus::Converged:
      return "converged";
    case FitStatus::MaxIterations:
      return "max-iterations";
    case FitStatus::Singular:
      return "singular";
    case FitStatus::Diverged:
      return "diverged";
    case FitStatus::LeftFrame:
      return "left-frame";
    case FitStatus::NoSignal:
      return "no-signal";
  }
  return "unknown";
}

int defaultStampHalfSize(const psf::Moffat& psf) noexcept {
  return std::max(2, static_cast<int>(std::ceil(3.0 * psf.fwhm())));
}

namespace {

struct Setup {
  std::vector<std::size_t> frames;
  std::vector<double> times;  // relative to the fit's reference time
  double tRefOffsetS = 0.0;
  std::array<bool, kParamCount> free{};
  int nFree = 0;
  int half = 0;
  double maxShift = 0.0;
};

Setup makeSetup(const FrameCube& cube, const FitOptions& o) {
  if (cube.empty()) throw InputError("co-moving fit: the cube has no frames");
  if (!(o.psf.radius > 0.0) || !(o.psf.beta > 1.0)) {
    throw InputError("co-moving fit: PSF needs R > 0 and beta > 1, got R=" + std::to_string(o.psf.radius) +
                     " beta=" + std::to_string(o.psf.beta));
  }
  if (o.stampHalfSize < 0) throw InputError("co-moving fit: negative stamp half-size");
  Setup s;
  const std::vector<double> all = cube.timeOffsetsS();
  s.frames = o.frames;
  if (s.frames.empty()) {
    s.frames.resize(cube.frameCount());
    std::iota(s.frames.begin(), s.frames.end(), std::size_t{0});
  }
  double mean = 0.0;
  for (std::size_t n : s.frames) {
    if (n >= cube.frameCount()) {
      throw InputError("co-moving fit: frame index " + std::to_string(n) + " out of range (cube has " +
                       std::to_string(cube.frameCount()) + " frames)");
    }
    mean += all[n];
  }
  mean /= static_cast<double>(s.frames.size());
  s.tRefOffsetS = o.tRefOffsetS.value_or(mean);
  for (std::size_t n : s.frames)
    s.times.push_back(all[n] - s.tRefOffsetS);
  s.free = {!o.fixVelocity, !o.fixVelocity, true, true, true, o.fitBackground};
  s.nFree = static_cast<int>(std::count(s.free.begin(), s.free.end(), true));
  s.half = o.stampHalfSize > 0 ? o.stampHalfSize : defaultStampHalfSize(o.psf);
  s.maxShift = o.maxShiftPx.value_or(static_cast<double>(s.half));
  return s;
}

detail::FitProblem makeProblem(const FrameCube& cube, const Setup& s, const FitOptions& o) {
  detail::FitProblem prob(cube, s.frames, s.times, o.psf, s.half);
  if (o.selfSubtraction && !o.selfSubtraction->empty()) {
    for (const std::size_t n : o.selfSubtraction->frames) {
      if (n >= cube.frameCount()) {
        throw InputError("co-moving fit: the background's frame " + std::to_string(n) +
                         " is out of range (cube has " + std::to_string(cube.frameCount()) + " frames)");
      }
    }
    const double clip = o.sigmaN && *o.sigmaN > 0.0 ? o.selfSubtraction->clipXi * *o.sigmaN
                                                    : std::numeric_limits<double>::infinity();
    prob.setSelfSubtraction(*o.selfSubtraction, s.tRefOffsetS, clip, o.sourceInBackground);
  }
  return prob;
}

// Solves (A + lambda diag(A)) d = b on the free parameters; false when singular.
bool solveStep(const ParamMatrix& a, const ParamVector& b, const std::array<bool, kParamCount>& free,
               double lambda, ParamVector& step) {
  ParamMatrix m = ParamMatrix::Identity();
  ParamVector rhs = ParamVector::Zero();
  for (int i = 0; i < kParamCount; ++i) {
    if (!free[i]) continue;
    rhs[i] = b[i];
    for (int j = 0; j < kParamCount; ++j) {
      if (free[j]) m(i, j) = a(i, j);
    }
    m(i, i) *= 1.0 + lambda;
  }
  // Scale to unit diagonal so the conditioning test is independent of parameter units.
  ParamVector d = m.diagonal().cwiseAbs().cwiseSqrt();
  if ((d.array() <= 0.0).any() || !d.allFinite()) return false;
  const ParamMatrix scaled = d.cwiseInverse().asDiagonal() * m * d.cwiseInverse().asDiagonal();
  Eigen::SelfAdjointEigenSolver<ParamMatrix> eig(scaled, Eigen::EigenvaluesOnly);
  if (eig.info() != Eigen::Success || eig.eigenvalues().minCoeff() < 1e-12) return false;
  step = d.cwiseInverse().asDiagonal() * scaled.ldlt().solve(d.cwiseInverse().asDiagonal() * rhs);
  return step.allFinite();
}

bool insideFrame(const FrameCube& cube, const FitParams& p) {
  return p.xc >= -0.5 && p.yc >= -0.5 && p.xc <= cube.width() - 0.5 && p.yc <= cube.height() - 0.5;
}

// The LM iterations; fills status, message, iterations and the cost history of `res`, returns the final p.
struct LmState {
  FitParams p;
  detail::NormalEquations ev;
};

bool offTrack(const FitParams& p, const FitParams& start, const Setup& s, double tHalf) {
  const double shift = std::hypot(p.xc - start.xc, p.yc - start.yc);
  const double vShift = std::hypot(p.v.vx - start.v.vx, p.v.vy - start.v.vy) * tHalf;
  return shift > s.maxShift || vShift > s.maxShift;
}

void runLm(const FrameCube& cube, const FitOptions& o, const Setup& s, detail::FitProblem& prob, LmState& st,
           FitResult& res, const IterationCallback& onIteration, CancelToken& cancel) {
  const double tHalf = 0.5 * effectiveDurationS(s.times);
  double lambda = 1e-3;
  double nu = 2.0;
  int recentres = 0;
  const auto report = [&](int it) {
    res.costHistory.push_back(st.ev.cost);
    if (onIteration) onIteration({it, st.ev.cost, lambda, st.p});
  };
  report(0);
  res.status = FitStatus::MaxIterations;
  res.message = "no convergence in " + std::to_string(o.maxIterations) + " iterations";
  int it = 0;
  while (it < o.maxIterations) {
    cancel.throwIfCancelled();
    ++it;
    bool converged = false;
    ParamVector step;
    if (!solveStep(st.ev.jtj, st.ev.jtr, s.free, lambda, step)) {
      res.status = FitStatus::Singular;
      res.message = "J^T J is singular at iteration " + std::to_string(it) + " (no signal in the stamp?)";
      break;
    }
    const FitParams trial = FitParams::fromVector(st.p.toVector() + step);
    detail::NormalEquations evTrial = prob.evaluate(trial, true);
    // Gain ratio of the actual to the predicted cost decrease (C = sum r^2, so C(p + d) ~ C - 2 d.Jr + dAd).
    const double predicted = 2.0 * step.dot(st.ev.jtr) - step.dot(st.ev.jtj * step);
    const double rho = predicted > 0 ? (st.ev.cost - evTrial.cost) / predicted : -1.0;
    if (std::isfinite(evTrial.cost) && evTrial.cost <= st.ev.cost) {
      const double dof = std::max<double>(1.0, static_cast<double>(st.ev.pixels) - s.nFree);
      const double dChi = step.dot(st.ev.jtj * step);
      converged = dChi < o.stepTolerance * st.ev.cost / dof;
      st.p = trial;
      st.ev = std::move(evTrial);
      // Nielsen's update: shrink lambda by up to 3x when the quadratic model predicted the decrease well.
      lambda *= std::max(1.0 / 3.0, 1.0 - std::pow(2.0 * std::clamp(rho, 0.0, 1.0) - 1.0, 3));
      lambda = std::max(lambda, 1e-12);
      nu = 2.0;
    } else {
      lambda *= nu;
      nu *= 2.0;
      converged = lambda > 1e12;  // no step lowers the cost: at the minimum to rounding
    }
    report(it);
    if (!insideFrame(cube, st.p)) {
      res.status = FitStatus::LeftFrame;
      res.message = "the fitted position left the frame";
      break;
    }
    if (offTrack(st.p, res.start, s, tHalf)) {
      res.status = FitStatus::Diverged;
      std::ostringstream m;
      m << "the track moved more than " << s.maxShift << " px from the start point";
      res.message = m.str();
      break;
    }
    if (!converged) continue;
    if (prob.centreDrift(st.p) >= 1 && recentres < o.maxRecentre) {
      ++recentres;
      prob.centreStamps(st.p);
      st.ev = prob.evaluate(st.p, true);
      lambda = 1e-3;
      nu = 2.0;
      continue;
    }
    res.status = FitStatus::Converged;
    res.message.clear();
    break;
  }
  res.iterations = it;
}

// Covariance (J^T J)^-1 C/dof on the free block; false when J^T J is singular.
bool fillCovariance(const Setup& s, const detail::NormalEquations& ev, const ParamMatrix& noise,
                    FitResult& res) {
  std::vector<int> idx;
  for (int i = 0; i < kParamCount; ++i) {
    if (s.free[i]) idx.push_back(i);
  }
  const int k = static_cast<int>(idx.size());
  Eigen::MatrixXd a(k, k);
  for (int i = 0; i < k; ++i) {
    for (int j = 0; j < k; ++j)
      a(i, j) = ev.jtj(idx[i], idx[j]);
  }
  const Eigen::VectorXd d = a.diagonal().cwiseSqrt();
  if ((d.array() <= 0.0).any() || !d.allFinite()) return false;
  const Eigen::MatrixXd scaled = d.cwiseInverse().asDiagonal() * a * d.cwiseInverse().asDiagonal();
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(scaled);
  if (eig.info() != Eigen::Success || eig.eigenvalues().minCoeff() < 1e-12) return false;
  const Eigen::MatrixXd inv =
      d.cwiseInverse().asDiagonal() *
      (eig.eigenvectors() * eig.eigenvalues().cwiseInverse().asDiagonal() * eig.eigenvectors().transpose()) *
      d.cwiseInverse().asDiagonal();
  const double s2 = res.rmsResidual * res.rmsResidual;
  res.covariance.setZero();
  for (int i = 0; i < k; ++i) {
    for (int j = 0; j < k; ++j)
      res.covariance(idx[i], idx[j]) = inv(i, j) * s2;
  }
  res.sigma = res.covariance.diagonal().cwiseMax(0.0).cwiseSqrt();
  Eigen::MatrixXd b(k, k);
  for (int i = 0; i < k; ++i) {
    for (int j = 0; j < k; ++j)
      b(i, j) = noise(idx[i], idx[j]);
  }
  const Eigen::MatrixXd sandwich = inv * b * inv;
  res.covarianceNoiseModel.setZero();
  for (int i = 0; i < k; ++i) {
    for (int j = 0; j < k; ++j)
      res.covarianceNoiseModel(idx[i], idx[j]) = sandwich(i, j);
  }
  res.sigmaNoiseModel = res.covarianceNoiseModel.diagonal().cwiseMax(0.0).cwiseSqrt();
  return true;
}

// Derived quantities: noise, Hessian errors, SNR, the paper's formula errors, stacks.
void finish(const FitOptions& o, const Setup& s, const detail::FitProblem& prob, const LmState& st,
            FitResult& res) {
  res.params = st.p;
  res.cost = st.ev.cost;
  res.pixels = st.ev.pixels;
  const double dof = std::max<double>(1.0, static_cast<double>(st.ev.pixels) - s.nFree);
  res.rmsResidual = std::sqrt(st.ev.cost / dof);
  res.sigmaN = o.sigmaN.value_or(res.rmsResidual);
  res.reducedChi2 = res.sigmaN > 0 ? st.ev.cost / (dof * res.sigmaN * res.sigmaN) : 0.0;
  const ParamMatrix noise =
      prob.noiseMoment(st.p, res.sigmaN * res.sigmaN, o.gain / std::max(1.0, o.excessNoise));
  if (!fillCovariance(s, st.ev, noise, res) && res.status == FitStatus::Converged) {
    res.status = FitStatus::Singular;
    res.message = "J^T J is singular at the solution; no uncertainties";
  }
  if (res.status == FitStatus::Converged && !(st.p.alpha > 0.0)) {
    res.status = FitStatus::NoSignal;
    res.message = "converged to a non-positive amplitude: no source at the start point";
  }
  const double w = o.psf.fwhm();
  res.tTotS = effectiveDurationS(s.times);
  res.sumP2 = pixelPsfSumOfSquares(o.psf);
  res.photonsPerFrame = o.gain * st.p.alpha * o.psf.integral();
  res.framesInside = prob.framesInside(st.p);
  const double nf = static_cast<double>(res.framesInside);
  // With the background's share of the source in the model (FitOptions::selfSubtraction), alpha is the
  // source's whole amplitude but only the part the background left can be detected.
  if (res.sigmaN > 0 && nf > 0)
    res.snr = detectionSnr(st.p.alpha, nf, res.sumP2, res.sigmaN) * prob.snrKept(st.p);
  // Least squares at low SNR scatters more than its covariance (the Fisher information) says; the excess
  // grows as 1 / SNR^2 (lowSnrVarianceFactor). Both covariances carry it; the paper's formulas do not.
  if (res.snr > 0.0) {
    const double f2 = lowSnrVarianceFactor(res.snr);
    res.covariance *= f2;
    res.sigma = res.covariance.diagonal().cwiseMax(0.0).cwiseSqrt();
    res.covarianceNoiseModel *= f2;
    res.sigmaNoiseModel = res.covarianceNoiseModel.diagonal().cwiseMax(0.0).cwiseSqrt();
  }
  if (res.photonsPerFrame > 0 && res.snr > 0) {
    res.sigmaPosPaper = positionSigmaPaper(res.photonsPerFrame, w, o.gain * res.sigmaN, nf);
    res.sigmaPosSnr = positionSigmaFromSnr(w, res.snr);
    if (res.tTotS > 0) res.sigmaVelPaper = velocitySigma(res.sigmaPosPaper, res.tTotS);
  }
  if (o.sigmaN && res.reducedChi2 > 4.0) {
    std::ostringstream m;
    m << "poor fit: reduced chi^2 = " << res.reducedChi2
      << " with the given sigma_n (saturated, blended or not PSF-like?)";
    res.warnings.push_back(m.str());
  }
  prob.stacks(st.p, res.dataStack, res.modelStack, res.residualStack);
}

}  // namespace

FitStacks stacksAt(const FrameCube& cube, const FitParams& params, const FitOptions& options) {
  const Setup s = makeSetup(cube, options);
  detail::FitProblem prob = makeProblem(cube, s, options);
  prob.centreStamps(params);
  FitStacks out;
  prob.stacks(params, out.data, out.model, out.residual);
  return out;
}

FitResult fitComoving(const FrameCube& cube, const FitParams& start, const FitOptions& options) {
  CancelToken never;
  return fitComoving(cube, start, options, {}, never);
}

FitResult fitComoving(const FrameCube& cube, const FitParams& start, const FitOptions& options,
                      const IterationCallback& onIteration, CancelToken& cancel) {
  const Setup s = makeSetup(cube, options);
  if (!std::isfinite(start.xc) || !std::isfinite(start.yc) || !std::isfinite(start.v.vx) ||
      !std::isfinite(start.v.vy) || !std::isfinite(start.i0)) {
    throw InputError("co-moving fit: the start point has a non-finite position, velocity or I0");
  }
  detail::FitProblem prob = makeProblem(cube, s, options);
  FitResult res;
  res.framesUsed = s.frames.size();
  res.freeParams = s.nFree;
  res.tRefOffsetS = s.tRefOffsetS;
  res.tRefMjd = cube.tRefMjd() + s.tRefOffsetS / kSecondsPerDay;
  LmState st;
  st.p = start;
  prob.centreStamps(st.p);
  if (!std::isfinite(st.p.alpha)) st.p = prob.linearAmplitude(st.p, options.fitBackground);
  res.start = st.p;
  st.ev = prob.evaluate(st.p, true);
  if (st.ev.pixels <= static_cast<std::size_t>(s.nFree)) {
    res.status = FitStatus::LeftFrame;
    res.message =
        "the stamp holds " + std::to_string(st.ev.pixels) + " usable pixels: track outside the frame";
    res.params = st.p;
    return res;
  }
  runLm(cube, options, s, prob, st, res, onIteration, cancel);
  finish(options, s, prob, st, res);
  return res;
}

ForcedPhotometry forcedPhotometry(const FrameCube& cube, const FitParams& track, const FitOptions& options,
                                  double sigmaN) {
  const Setup s = makeSetup(cube, options);
  detail::FitProblem prob = makeProblem(cube, s, options);
  prob.centreStamps(track);
  // One set of sums for the amplitude and its error: the track's amplitude decides which background terms
  // the clip left out (FitOptions::selfSubtraction) in both.
  const auto l = prob.linearSums(track);
  FitParams p = track;
  p.alpha = std::numeric_limits<double>::quiet_NaN();
  p = detail::FitProblem::linearAmplitude(p, options.fitBackground, l);
  ForcedPhotometry f;
  f.alpha = p.alpha;
  f.i0 = p.i0;
  f.pixels = static_cast<std::size_t>(l.n);
  f.framesInside = prob.framesInside(track);
  const double det = l.n * l.spp - l.sp * l.sp;
  const double var = options.fitBackground ? (det > 0 ? l.n / det : 0.0) : (l.spp > 0 ? 1.0 / l.spp : 0.0);
  f.sigmaAlpha = sigmaN * std::sqrt(var);
  f.snr = f.sigmaAlpha > 0 ? f.alpha / f.sigmaAlpha : 0.0;
  // With background terms, the SNR a filter matched to P sees (as FitResult::snr), not the terms' repeat of
  // other frames' flux: x sum E P / sqrt(sum E^2 sum P^2).
  if (prob.hasBackgroundTerms() && l.spp > 0 && l.sPP > 0) f.snr *= l.sep / std::sqrt(l.spp * l.sPP);
  return f;
}

}  // namespace st::fit

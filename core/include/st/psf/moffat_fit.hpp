#pragma once
// Fitting the Moffat PSF of the paper (\label{MoffatPsf}) to one star: model
//   M(x, y) = B + A * <P(x - x0, y - y0; R, beta)>_pixel
// (averaged over MoffatFitOptions::smear when the image is a stack with known blur, st/psf/stack_smear.hpp),
// where <.>_pixel is the mean of P over the pixel (the detector integrates over its pixels, so fitting a
// point-sampled P to the data would bias R by ~1-3% at FWHM ~3 px). Six parameters (x0, y0, R, beta, A, B)
// by Levenberg-Marquardt with an analytic Jacobian (Eigen dense solves). The radial profile of a star
// (binned mean vs radius) with the fitted curve, as in the paper's Fig. 4.
#include <string>
#include <vector>

#include "st/common/image.hpp"
#include "st/psf/moffat.hpp"
#include "st/psf/stack_smear.hpp"

namespace st::psf {

/// Bounds of beta in the fit; a fit that ends on one is not a Moffat profile (measurePsf rejects it).
inline constexpr double kFitMinBeta = 1.05;
inline constexpr double kFitMaxBeta = 50.0;

/// True when a fitted beta ends on (within 1% of) one of those bounds.
[[nodiscard]] inline bool betaAtFitBound(double beta) noexcept {
  return beta <= kFitMinBeta * 1.01 || beta >= kFitMaxBeta * 0.99;
}

/// How far (px) a star's fitted centre may lie from where it was found, for a fit of FWHM `fwhmPx`: farther,
/// the fit is of something else (measurePsf rejects it; fitMoffat does not refine such a fit pinned at a beta
/// bound with the smear).
[[nodiscard]] inline double fitWanderLimitPx(double fwhmPx) noexcept {
  return fwhmPx > 3.0 ? fwhmPx : 3.0;
}

/// Options of fitMoffat. Defaults suit stars of FWHM 2-15 px.
struct MoffatFitOptions {
  int halfSize = 0;         ///< stamp half-size, px; 0 = chosen from the star (4 FWHM, clamped to 6..30)
  int subsamples = 4;       ///< n x n Gauss-Legendre rule for the pixel mean (1..5); 1 = point sampling
  int maxIterations = 200;  ///< LM iterations before giving up
  double betaGuess = 3.0;   ///< starting beta
  double noiseSigma = 0.0;  ///< per-pixel noise of the image; 0 = estimate from the residuals
  bool ignoreZeros = true;  ///< skip pixels that are exactly 0 (zeroed by earlier stages, masked)
  /// The blur of the image beyond the PSF (e.g. stackSmear of a sky-rate stack: trails and shift rounding).
  /// When given, the model is A * sum_k w_k <P(x - x0 - dx_k, y - y0 - dy_k)>_pixel + B, and R, beta are
  /// those of the PSF itself. Empty = the image is the PSF. The smeared model refines the plain one's fit;
  /// a plain fit whose beta ends on a bound and whose centre lies more than fitWanderLimitPx + 2 px from the
  /// guess (no star's profile) is returned as it is.
  SmearKernel smear;
  /// The amplitude below which the caller rejects the fit (measurePsf: minPeakSnr x the image noise); 0 =
  /// none. A plain fit whose amplitude stays below half of it even with the smear's loss of peak put back
  /// (divided by sum_k w_k P(dx_k, dy_k) / P(0, 0) of the plain fit's profile) is not refined with the
  /// smear: it is returned as it is, to be rejected.
  double rejectBelowAmplitude = 0.0;
};

/// Why the LM iterations stopped.
enum class FitConvergence {
  RelativeReduction,  ///< chi^2 changed by less than 1e-10 relative (converged)
  SmallStep,          ///< parameter step below 1e-9 relative (converged)
  SmallGradient,      ///< gradient below tolerance (converged)
  MaxIterations,      ///< not converged
  Diverged,           ///< damping grew without bound; no step reduces chi^2 (not converged)
};

/// Human-readable text for a FitConvergence value.
std::string toString(FitConvergence c);

/// The result of one Moffat fit. Positions are 0-based pixel coordinates of the whole image.
struct MoffatFit {
  double x0 = 0.0, y0 = 0.0;  ///< centre, px
  Moffat model;               ///< R (px) and beta
  double amplitude = 0.0;     ///< A: the peak of the continuous profile above background, image units
  double background = 0.0;    ///< B, image units
  /// 1-sigma uncertainties of (x0, y0, R, beta, A, B), from the inverse of J^T J scaled by the residual
  /// variance (or by noiseSigma^2 when given).
  double sigmaX0 = 0.0, sigmaY0 = 0.0, sigmaRadius = 0.0, sigmaBeta = 0.0, sigmaAmplitude = 0.0,
         sigmaBackground = 0.0;
  double sigmaFwhm = 0.0;    ///< 1-sigma of W, propagated with the R-beta covariance
  double residualRms = 0.0;  ///< rms of (data - model) over the stamp, image units
  double reducedChi2 = 0.0;  ///< sum of squared residuals / (pixels - 6) / noiseSigma^2 (1 when not given)
  int pixels = 0;            ///< pixels used
  int iterations = 0;
  FitConvergence convergence = FitConvergence::MaxIterations;
  [[nodiscard]] bool converged() const noexcept {
    return convergence != FitConvergence::MaxIterations && convergence != FitConvergence::Diverged;
  }
  /// FWHM W = 2 R sqrt(2^(1/beta) - 1), px.
  [[nodiscard]] double fwhm() const noexcept { return model.fwhm(); }
};

/// Fits the Moffat profile to the star near (xGuess, yGuess) in `image`. The stamp is clipped to the image.
/// Throws st::InputError when the stamp has fewer than 20 usable pixels or the guess is outside the image.
/// A fit that does not converge is returned with its convergence reason; the caller decides.
MoffatFit fitMoffat(const Image& image, double xGuess, double yGuess, const MoffatFitOptions& options = {});

/// Why a fit that converged numerically still does not describe a star near the guess, or "" when it
/// does: the centre outside the image or more than max(5 px, 2 FWHM) from (xGuess, yGuess); a FWHM below
/// 0.5 px (narrower than a pixel: a hot pixel or noise) or above a quarter of the smaller image side; beta at
/// the fit's upper bound region (>= 40: no wings, a flat-topped blob). A radial-profile fit with an absurd
/// centre (e.g. "(-1578.8, 7430.4): FWHM 0.05 px, beta 50.00") is then reported as rejected, not converged.
[[nodiscard]] std::string implausibleFit(const MoffatFit& fit, double xGuess, double yGuess, int width,
                                         int height);

/// One bin of a radial profile.
struct RadialBin {
  double radius = 0.0;  ///< mean distance of the bin's pixel centres from the centre, px
  double mean = 0.0;    ///< mean of (data - background) over the bin
  double model = 0.0;   ///< mean of the fitted profile (without background) over the same pixels
  int count = 0;        ///< pixels in the bin
};

/// The radial profile of the star of `fit` in `image`: pixels within maxRadius (px) of (x0, y0) binned by
/// distance in bins of binWidth px (default 0.5), background removed, with the fitted curve averaged over
/// the same pixels. Exact-zero pixels are skipped (masked). Empty bins are left out.
std::vector<RadialBin> radialProfile(const Image& image, const MoffatFit& fit, double maxRadius,
                                     double binWidth = 0.5, int subsamples = 4);

}  // namespace st::psf

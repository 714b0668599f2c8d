#pragma once
// Co-moving PSF fitting (paper §3.2, \label{comoving_lsq}): least squares of the zero-biased, unfiltered
// frames against alpha P(x - x_c - vx (t_n - t_ref), y - y_c - vy (t_n - t_ref)) + I0 over a stamp that
// follows the track, for (vx, vy, x_c, y_c, alpha, I0). P is the pixel-integrated Moffat of pixel_psf.hpp
// (3x3 sub-sampling, like the simulator's pixel integration). Times are real frame times
// (FrameCube::timeOffsetsS), never frame indices, so uneven cadences are handled.
//
// The minimiser is Levenberg-Marquardt with Marquardt's diagonal scaling and an analytic Jacobian. J^T J and
// J^T r are accumulated over all frames' stamp pixels without storing J, in parallel over frames
// (st::parallelFor, one partial sum per chunk, added in chunk order so results do not depend on threads).
// The stamp of frame n is a (2h+1)^2 square centred on the rounded track position; it is fixed during one
// LM run (so every cost compared is over the same pixels) and re-centred, at most FitOptions::maxRecentre
// times, when the converged track has moved by a pixel or more.
#include <Eigen/Dense>
#include <array>
#include <cstddef>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "st/common/frame_cube.hpp"
#include "st/common/image.hpp"
#include "st/common/progress.hpp"
#include "st/common/units.hpp"
#include "st/psf/moffat.hpp"
#include "st/search/types.hpp"
#include "st/stats/background.hpp"

namespace st::fit {

/// Index of each parameter in vectors and matrices (the paper's order).
enum ParamIndex : int { kVx = 0, kVy = 1, kXc = 2, kYc = 3, kAlpha = 4, kI0 = 5, kParamCount = 6 };

using ParamVector = Eigen::Matrix<double, kParamCount, 1>;
using ParamMatrix = Eigen::Matrix<double, kParamCount, kParamCount>;

/// The fitted quantities. Positions are 0-based pixels at the fit's reference time; alpha is the PSF peak
/// amplitude per frame in data units (P has peak 1), I0 the constant level per pixel per frame.
struct FitParams {
  Velocity v;          ///< px/s
  double xc = 0.0;     ///< column at the reference time
  double yc = 0.0;     ///< row at the reference time
  double alpha = 0.0;  ///< amplitude; NaN in a start point means "estimate it" (linear least squares)
  double i0 = 0.0;     ///< background level left in the zero-biased frames

  [[nodiscard]] ParamVector toVector() const;
  [[nodiscard]] static FitParams fromVector(const ParamVector& p);
};

/// Start point from a search candidate: its cell (x, y) at t_ref and grid velocity; alpha to be estimated.
[[nodiscard]] FitParams startFromCandidate(const search::Candidate& candidate);

enum class FitStatus {
  Converged,      ///< the cost stopped decreasing; the step is far below the statistical error
  MaxIterations,  ///< FitOptions::maxIterations reached before convergence
  Singular,       ///< J^T J cannot be inverted (no signal in the stamp, or degenerate parameters)
  Diverged,       ///< non-finite cost, or the track moved further from the start than FitOptions allows
  LeftFrame,      ///< the fitted position left the frame, or too few in-frame pixels remain
  NoSignal,       ///< converged to alpha <= 0: nothing to measure at the start point
};
[[nodiscard]] const char* toString(FitStatus status) noexcept;

struct FitOptions {
  psf::Moffat psf;                   ///< R, beta from the PSF fit
  int stampHalfSize = 0;             ///< h, pixels; 0 = ceil(3 W) (about 3 FWHM each side)
  int maxIterations = 100;           ///< LM iterations (accepted or not), summed over re-centrings
  double stepTolerance = 1e-6;       ///< converged when the step's chi^2 change dP^T J^T J dP < tol * s^2
  bool fixVelocity = false;          ///< keep (vx, vy) at the start value (static stars, segment fits)
  bool fitBackground = true;         ///< fit I0; false keeps it at the start value (frames are zero-biased)
  std::optional<double> sigmaN;      ///< per-pixel noise of one frame (data units); default: from residuals
  double gain = 1.0;                 ///< photons per data unit (e-/ADU) for photon counts and eq:sig
  /// The source's photon-noise variance over Poisson's, in the noise model's covariance: 2 for an EMCCD's
  /// multiplication register at high gain (astro::excessNoiseFactor), 1 otherwise. eq:sig stays the paper's.
  double excessNoise = 1.0;
  int maxRecentre = 3;               ///< stamp re-centrings after convergence
  std::optional<double> maxShiftPx;  ///< Diverged when the position moves further from the start (default h)
  std::vector<std::size_t> frames;   ///< frames to use (indices into the cube); empty = all
  /// Reference time of the fitted position, seconds from the cube's t_ref. Default: the mean time of the
  /// frames used (0 for the whole cube, the paper's "mid epoch").
  std::optional<double> tRefOffsetS;
  /// How the frames' per-pixel background was made (pipeline::Prepared::backgroundWindows). The mover's own
  /// flux in the frames averaged into frame n's background was subtracted with it, so the model of frame n
  /// is alpha (P(q - r_n) - sum_m P(q - r_m) / M_n) + I0 over the M_n frames m of n's background (those
  /// within a FWHM / 8 of each other taken at their mean time; a term alpha P above clipXi sigma_n left out,
  /// as the clip leaves such a sample out). A slow mover otherwise loses flux and, at the ends of its
  /// track, is pulled outward. The same windows make the frames' noise correlated at each pixel (frames
  /// share background frames); the noise-model covariance (sigmaNoiseModel) carries those correlations.
  /// Unset (or empty): the model and the covariance are the paper's.
  std::optional<stats::PixelBackgroundWindows> selfSubtraction;
  /// False: the source was left out of its background (a mover the static-source search masked there):
  /// selfSubtraction's noise correlations are kept, its background terms are not.
  bool sourceInBackground = true;
};

/// One LM iteration, for a live cost plot.
struct FitIteration {
  int iteration = 0;  ///< 0 = the start point
  double cost = 0.0;  ///< the paper's C (sum of squared residuals, data units^2)
  double lambda = 0.0;
  FitParams params;
};
using IterationCallback = std::function<void(const FitIteration&)>;

struct FitResult {
  FitParams start;
  FitParams params;
  FitStatus status = FitStatus::Diverged;
  std::string message;  ///< why, in words, when status != Converged
  int iterations = 0;
  std::vector<double> costHistory;  ///< cost at the start and after each iteration
  double cost = 0.0;                ///< final C
  std::size_t pixels = 0;           ///< stamp pixels summed over frames
  std::size_t framesUsed = 0;       ///< frames given to the fit
  std::size_t framesInside = 0;     ///< of those, frames whose fitted track is inside the frame (N_in): the
                                    ///< N_f of detection_snr and eq:sig
  int freeParams = 0;
  double rmsResidual = 0.0;  ///< sqrt(C / (pixels - freeParams)), data units
  double sigmaN = 0.0;       ///< noise used for SNR: FitOptions::sigmaN or rmsResidual
  double reducedChi2 = 0.0;  ///< C / (dof sigma_n^2); 1 by construction without a given sigma_n
  ParamMatrix covariance = ParamMatrix::Zero();  ///< (J^T J)^-1 * C/dof; zero rows for fixed params
  ParamVector sigma = ParamVector::Zero();       ///< sqrt of the covariance diagonal (Hessian errors)
  /// Sandwich covariance A^-1 (J^T V J) A^-1 (A = J^T J) with the per-pixel variance V = sigma_n^2 +
  /// alpha P / gain: background plus the source's photon noise. The Hessian form above assumes one variance
  /// for every pixel and so under-states the error when the source's photon noise matters (it gives only
  /// eq:sig's background term); this one reproduces both terms of eq:sig.
  ParamMatrix covarianceNoiseModel = ParamMatrix::Zero();
  ParamVector sigmaNoiseModel = ParamVector::Zero();
  double tRefMjd = 0.0;          ///< epoch of (xc, yc)
  double tRefOffsetS = 0.0;      ///< the same, seconds from the cube's t_ref
  double tTotS = 0.0;            ///< effectiveDurationS of the frames used (vel_snr's T_tot)
  double sumP2 = 0.0;            ///< pixelPsfSumOfSquares
  double photonsPerFrame = 0.0;  ///< gain * alpha * sum P  (paper's N_ph)
  double snr = 0.0;  ///< detection_snr with sigma_n (x the share FitOptions::selfSubtraction leaves)
  double sigmaPosPaper = 0.0;    ///< eq:sig with N_ph, W, gain*sigma_n, N_f (px)
  double sigmaPosSnr = 0.0;      ///< cent_snr 0.65 W / SNR (px)
  double sigmaVelPaper = 0.0;    ///< vel_snr from sigmaPosPaper and tTotS (px/s)
  /// Stacks over the frames used, on a (2h+1)^2 grid centred on the rounded fitted track (integer shifts,
  /// no interpolation): the data, the model, and data - model (the residual image).
  Image dataStack;
  Image modelStack;
  Image residualStack;
  std::vector<std::string> warnings;
  [[nodiscard]] bool ok() const noexcept { return status == FitStatus::Converged; }
};

/// The least-squares fit's variance over its covariance's (the Fisher information's) at detection SNR `snr`:
/// 1 + k / SNR^2, k = kLowSnrVarianceCoefficient. Measured on the simulator with the background removed
/// exactly (paper-neo frames minus their noise-free scene: noise and the asteroid only, the true PSF and
/// noise; 100 seeds, 2026-12-05): the pulls of 4-segment positions (SNR ~7.5) had rms 1.12 and of 8-segment
/// ones (SNR ~5.3) 1.23, k = 14.6 and 14.3; Poisson noise without the EM register gave the same (40 seeds).
/// The next order of the estimator's variance beyond the Fisher bound falls as 1 / SNR^2; at SNR 15 the
/// factor is 1.064 (errors x 1.03). fitComoving multiplies both covariances by it. 1 for SNR <= 0.
inline constexpr double kLowSnrVarianceCoefficient = 14.5;
[[nodiscard]] double lowSnrVarianceFactor(double snr) noexcept;

/// Runs the co-moving fit on a zero-biased, unfiltered cube. `onIteration` (may be empty) is called on the
/// calling thread after every iteration; `cancel` is polled once per iteration (throws st::Cancelled).
/// Throws st::InputError for bad options (non-positive R or beta <= 1, an empty cube, frame indices out
/// of range); every failure to fit is a status, never NaNs in `params`.
[[nodiscard]] FitResult fitComoving(const FrameCube& cube, const FitParams& start, const FitOptions& options,
                                    const IterationCallback& onIteration, CancelToken& cancel);
[[nodiscard]] FitResult fitComoving(const FrameCube& cube, const FitParams& start, const FitOptions& options);

/// Forced photometry on a fixed track: linear least squares for (alpha, I0) over the same stamps as the fit,
/// with the position and velocity of `track` held. sigmaAlpha = sigma_n sqrt(n / (n sum P^2 - (sum P)^2))
/// (sqrt(1 / sum P^2) when I0 is held); snr = alpha / sigmaAlpha, which for many frames is detection_snr.
struct ForcedPhotometry {
  double alpha = 0.0;
  double i0 = 0.0;
  double sigmaAlpha = 0.0;
  double snr = 0.0;
  std::size_t pixels = 0;
  std::size_t framesInside = 0;  ///< frames whose track is inside the frame
};
/// `sigmaN` is the per-pixel noise of one frame (data units); options.frames / tRefOffsetS / psf /
/// stampHalfSize / fitBackground apply as in fitComoving.
[[nodiscard]] ForcedPhotometry forcedPhotometry(const FrameCube& cube, const FitParams& track,
                                                const FitOptions& options, double sigmaN);

/// The stamp half-size FitOptions::stampHalfSize = 0 stands for: ceil(3 W).
[[nodiscard]] int defaultStampHalfSize(const psf::Moffat& psf) noexcept;

/// The data, model and residual stacks of the co-moving model `params` (FitResult's dataStack, modelStack,
/// residualStack, computed the same way: stamps of `options` centred on the rounded track of `params` in every
/// frame the fit would use, times relative to its reference time). For the live residual while a fit
/// converges. Throws st::InputError for the options fitComoving refuses. Cost: one pass over the stamps.
struct FitStacks {
  Image data, model, residual;
};
[[nodiscard]] FitStacks stacksAt(const FrameCube& cube, const FitParams& params, const FitOptions& options);

}  // namespace st::fit

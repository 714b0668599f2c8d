#pragma once
// Segment checks (paper §4.4 and §5.1, fig_4epoch): the cube is split into K equal-time segments (default
// 4), each is stacked at the fitted velocity and measured; a real moving source shows in every segment, at
// the SNR the whole fit predicts scaled by sqrt(N_k / N_f), and its segment positions lie on the fitted
// track. Transients (signal in one segment only), cosmic-ray chains and detections stitched together from
// unrelated blips fail one of these tests and are flagged for a human.
#include <cstddef>
#include <string>
#include <vector>

#include "st/common/frame_cube.hpp"
#include "st/common/image.hpp"
#include "st/common/progress.hpp"
#include "st/fit/comoving_fit.hpp"

namespace st::vet {

struct SegmentOptions {
  int segments = 4;  ///< K (paper §5.1: 4 segments of ~7.8 s in 30 s)
  /// A segment "misses" the signal when its forced SNR is below expected - missingSigma (a deficit of that
  /// many standard deviations, the forced SNR having unit noise) AND below missingFraction * expected.
  double missingSigma = 3.0;
  double missingFraction = 0.5;
  /// Segment positions (or fluxes) are inconsistent with one moving source when the chi^2 probability of
  /// their deviations is below this.
  double minProbability = 1e-3;
};

struct SegmentMeasurement {
  int index = 0;
  std::vector<std::size_t> frames;  ///< cube frame indices in this segment
  double tMidOffsetS = 0.0;         ///< mean time of its frames, seconds from the cube's t_ref
  double predictedX = 0.0;          ///< the whole fit's track at tMidOffsetS
  double predictedY = 0.0;
  /// Forced photometry at the predicted track (always measured; unbiased even where there is no signal).
  double forcedAlpha = 0.0;
  double forcedSigmaAlpha = 0.0;
  double forcedSnr = 0.0;
  std::size_t framesInside = 0;  ///< frames of this segment whose predicted track is inside the frame
  double expectedSnr = 0.0;      ///< whole-fit SNR * sqrt(framesInside_k / framesInside of the whole fit)
  bool missing = false;
  /// Fit of the segment's frames with the velocity held at the whole fit's (position, alpha, I0 free).
  fit::FitStatus fitStatus = fit::FitStatus::Diverged;
  double x = 0.0, y = 0.0;            ///< fitted position at tMidOffsetS (when fitStatus is Converged)
  double sigmaX = 0.0, sigmaY = 0.0;  ///< noise-model errors of x, y
  double snr = 0.0;                   ///< detection_snr of the segment fit
  double photonsPerFrame = 0.0;       ///< gain * forcedAlpha * sum P
  /// The segment fit itself (its tRefOffsetS is tMidOffsetS, its tRefMjd that time's MJD): the position's
  /// covariance and epoch, for the segment's own astrometry (astro::skyMeasurement).
  fit::FitResult fit;
  Image stack;  ///< IPSA stack of the segment at the fitted velocity, centred on the track
};

struct SegmentReport {
  std::vector<SegmentMeasurement> segments;
  double positionChi2 = 0.0;  ///< sum over converged segments of the normalised position deviations^2
  int positionDof = 0;        ///< 2 * converged - 4 (the track was fitted to the same data); 0 = untested
  double positionProbability = 1.0;
  double fluxChi2 = 0.0;  ///< forced alphas about their weighted mean
  int fluxDof = 0;
  double fluxProbability = 1.0;
  bool missingSignal = false;
  bool offTrack = false;
  bool fluxInconsistent = false;
  std::vector<std::string> reasons;  ///< one line per flag, in words
  [[nodiscard]] bool flagged() const noexcept { return missingSignal || offTrack || fluxInconsistent; }
};

/// Splits frames by time into k equal-time segments over [first, last] mid-time; returns frame indices per
/// segment (a segment may be empty when the frames have a gap). Throws st::InputError for k < 1 or
/// k > frames.
[[nodiscard]] std::vector<std::vector<std::size_t>> splitEqualTime(const std::vector<double>& timesS, int k);

/// IPSA over a stamp (ARCHITECTURE.md convention): S(i, j) = sum_n F_n(cx + i + round(vx (t_n - t0)),
/// cy + j + round(vy (t_n - t0))) for i, j in [-h, h], with (cx, cy) = the rounded (x, y) at time t0
/// (seconds from the cube's t_ref), shifts from st::stack::ipsaShifts (the search's rounding). Out-of-frame
/// and masked samples contribute nothing. Image (2h+1)^2. A stamp, not st::stack::stackIpsa's whole frame,
/// because a segment is a subset of frames and copying them into a sub-cube would copy the data.
[[nodiscard]] Image stackStamp(const FrameCube& cube, const std::vector<std::size_t>& frames, double x,
                               double y, Velocity v, double t0OffsetS, int half);

/// Runs the segment checks on the track of a whole-cube fit `fit` made with `fitOptions` (PSF, gain, stamp;
/// its sigma_n is reused so that segment SNRs are on the whole fit's scale). The fit need not have
/// converged (a transient often makes it wander), but it must have a noise estimate: throws
/// st::InputError when fit.sigmaN <= 0 (e.g. a fit that left the frame). Polls `cancel`.
[[nodiscard]] SegmentReport checkSegments(const FrameCube& cube, const fit::FitResult& fit,
                                          const fit::FitOptions& fitOptions, const SegmentOptions& options,
                                          CancelToken& cancel);

/// Upper tail probability of a chi^2 with `dof` degrees of freedom (regularised incomplete gamma Q(dof/2,
/// chi2/2)); 1 for dof <= 0.
[[nodiscard]] double chiSquareSurvival(double chi2, int dof);

}  // namespace st::vet

#pragma once
// The candidate fit step (issue 18 §2): the co-moving PSF fit of one search candidate with its segment check
// and sky position, as the typed FitSummary every front end stores (`search --fit`, the demo, the GUI's Fit
// panel).
#include "st/candidate/candidate_measurement.hpp"
#include "st/common/progress.hpp"
#include "st/fit/comoving_fit.hpp"
#include "st/pipeline/preprocess.hpp"
#include "st/search/types.hpp"

namespace st::candidate {

/// The SNR a tracklet's positions are cut for: the paper's detection threshold (§4.4).
inline constexpr double kTrackletSnr = 7.0;

/// How many equal-time segments a fit of SNR `snr` is cut into for its tracklet (one position each, the
/// positions of an MPC submission): as many as keep each segment at kTrackletSnr, floor((snr / 7)^2), at
/// least 2 (the fewest positions the MPC links an object from) and at most 4 (the segment check's K). SNR
/// 15.9 (the demo): 4 segments of SNR ~8; 12: 2 of ~8.5; below 9.9 each of the 2 is below 7.
[[nodiscard]] int trackletSegments(double snr) noexcept;

/// Whether a source at (x, y) px is one of `movers` (within 2 FWHM + 2 px of one marked moving): the
/// movers the static-source search found (pipeline::Prepared::movers), whose streaks were left out of the
/// per-pixel background, so that their flux is not in it (fit::FitOptions::sourceInBackground = false).
[[nodiscard]] bool amongLeftOutMovers(const std::vector<detect::MovingSource>& movers, double psfFwhmPx,
                                      double x, double y);

/// The options fitCandidate fits `candidate` with (the live residual stacks of a front end use them too).
[[nodiscard]] fit::FitOptions fitOptions(const FrameCube& frames, const pipeline::Prepared& products,
                                         const search::Candidate& candidate);

/// Fits `candidate` on the zero-biased `frames` with the PSF, sigma_n and sky rate of `products` (its own
/// `frames` are not read; the GUI keeps them in its unfiltered cube), with the photo-electrons per count and
/// the excess noise of the frames' header (astro::photoelectronsPerCount, excessNoiseFactor), and the
/// per-pixel background's windows of `products` (fit::FitOptions::selfSubtraction: the mover's own flux in
/// its background and the frames' correlated background noise; not its flux for a mover the static-source
/// search left out of the background):
/// status, position at t_ref, velocity, noise-model and paper uncertainties, photons per frame, SNR; the
/// segment check (K = 4, vet::checkSegments) when sigma_n is known, and, when the fit converged, the
/// tracklet: trackletSegments(SNR) segments (the check's own when that is 4), each segment's position where
/// its fit converged, its signal is not missing and it lies within 5 sigma of the whole fit's track, with
/// RA/Dec at its own time when the frames have a WCS; RA/Dec, rate and position angle of the whole fit when
/// the frames have a WCS and the fit converged. `onIteration` sees every accepted step (calling thread);
/// `result` (may be null) receives the whole fit (covariances, stacks, cost history). Throws st::Cancelled.
[[nodiscard]] FitSummary fitCandidate(const FrameCube& frames, const pipeline::Prepared& products,
                                      const search::Candidate& candidate, CancelToken& cancel,
                                      const fit::IterationCallback& onIteration = {},
                                      fit::FitResult* result = nullptr);

/// The same on the zero-biased frames of `prepared`.
[[nodiscard]] FitSummary fitCandidate(const pipeline::Prepared& prepared, const search::Candidate& candidate,
                                      CancelToken& cancel);

}  // namespace st::candidate

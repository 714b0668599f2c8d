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

/// Fits `candidate` on the zero-biased `frames` with the PSF, sigma_n and sky rate of `products` (its own
/// `frames` are not read; the GUI keeps them in its unfiltered cube), with the photo-electrons per count and
/// the excess noise of the frames' header (astro::photoelectronsPerCount, excessNoiseFactor):
/// status, position at t_ref, velocity, noise-model and paper uncertainties, photons per frame, SNR; the
/// segment check (K = 4, vet::checkSegments) when sigma_n is known; RA/Dec, rate and position angle when the
/// frames have a WCS and the fit converged. `onIteration` sees every accepted step (calling thread);
/// `result` (may be null) receives the whole fit (covariances, stacks, cost history). Throws st::Cancelled.
[[nodiscard]] FitSummary fitCandidate(const FrameCube& frames, const pipeline::Prepared& products,
                                      const search::Candidate& candidate, CancelToken& cancel,
                                      const fit::IterationCallback& onIteration = {},
                                      fit::FitResult* result = nullptr);

/// The same on the zero-biased frames of `prepared`.
[[nodiscard]] FitSummary fitCandidate(const pipeline::Prepared& prepared, const search::Candidate& candidate,
                                      CancelToken& cancel);

}  // namespace st::candidate

#pragma once
// The co-moving PSF fit of one search candidate with its segment checks and sky position, as the JSON
// object the CLI reports put under a candidate's "fit" key (shared by `search --fit` and `demo`).
#include <nlohmann/json.hpp>

#include "st/common/progress.hpp"
#include "st/fit/comoving_fit.hpp"
#include "st/pipeline/preprocess.hpp"
#include "st/search/types.hpp"

namespace st::app {

/// Fits `candidate` on the zero-biased frames of `prepared` with its PSF and sigma_n (gain in e-/ADU for
/// photon counts): status, position at t_ref, velocity, noise-model uncertainties, the paper's sigma
/// formulas, photons per frame, SNR; the segment check (K = 4) flags and per-segment SNRs; and RA/Dec, rate
/// and position angle when the frames have a WCS. Throws st::Cancelled.
nlohmann::json fitCandidateJson(const pipeline::Prepared& prepared, const search::Candidate& candidate,
                                double gain, CancelToken& cancel);

/// The same with the zero-biased frames held apart from the other products (the GUI keeps them in its
/// unfiltered cube; `products.frames` is not read). `onIteration` sees every accepted step of the fit (from
/// the calling thread). `result` (may be null) receives the whole fit (covariances, stacks, cost history).
nlohmann::json fitCandidateJson(const FrameCube& frames, const pipeline::Prepared& products,
                                const search::Candidate& candidate, double gain, CancelToken& cancel,
                                const fit::IterationCallback& onIteration = {},
                                fit::FitResult* result = nullptr);

}  // namespace st::app

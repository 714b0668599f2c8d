#pragma once
// The co-moving fit as the GUI calls it (CoreServices::fitCandidate): app::fitCandidateJson on the
// unfiltered frames with the pre-processing's PSF and sigma_n, the GAIN keyword for photon counts, and a
// live residual image (data - model summed along the current track) at most every kResidualIntervalMs.
#include "core_services.hpp"

namespace st::app {

/// Minimum time between two live residual images (ms): each costs one pass over the stamps of every frame.
inline constexpr int kResidualIntervalMs = 150;

/// Data - model of the co-moving model `p` (pixel-integrated Moffat `psf`, stamp half-size `half`), summed
/// over the frames of `frames` on a (2 half + 1)^2 grid centred on the rounded track of each frame (the
/// layout of fit::FitResult::residualStack, the whole cube with t_ref as reference time). Out-of-frame,
/// masked and non-finite samples are skipped.
[[nodiscard]] Image residualAlongTrack(const FrameCube& frames, const fit::FitParams& p,
                                       const psf::Moffat& psf, int half);

/// CoreServices::fitCandidate: throws st::InputError when pre-processing kept no unfiltered frames or
/// products (PSF, sigma_n).
[[nodiscard]] ui::FitOutcome fitCandidate(const ui::PreparedView& prepared,
                                          const search::Candidate& candidate, CancelToken& cancel,
                                          const ui::FitStepCallback& onStep);

}  // namespace st::app

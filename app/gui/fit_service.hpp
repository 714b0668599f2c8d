#pragma once
// The co-moving fit as the GUI calls it (CoreServices::fitCandidate): candidate::fitCandidate on the
// unfiltered frames with the pre-processing's PSF and sigma_n, the GAIN keyword for photon counts, and a
// live residual image (fit::stacksAt) at most every kResidualIntervalMs.
#include "core_services.hpp"

namespace st::app {

/// Minimum time between two live residual images (ms): each costs one pass over the stamps of every frame.
inline constexpr int kResidualIntervalMs = 150;

/// CoreServices::fitCandidate: throws st::InputError when pre-processing kept no unfiltered frames or
/// products (PSF, sigma_n).
[[nodiscard]] ui::FitOutcome fitCandidate(const ui::PreparedView& prepared,
                                          const search::Candidate& candidate, CancelToken& cancel,
                                          const ui::FitStepCallback& onStep);

}  // namespace st::app

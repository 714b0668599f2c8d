#pragma once
// The noise of the search's statistic, measured on the cube itself. Zhai et al. (2014) derive Prob_false
// "by assuming the background fluctuates independently with a Gaussian statistics": SNR = S / (sigma_F
// sqrt(N_in)) then has unit variance in every cell. Real frames break the assumption (a residual that stays
// put from frame to frame adds coherently along a slow track; the Lowell 42-inch frames' statistic
// has 1.06 times the unit's spread over the search's grid and 1.07-1.09 on star-free tracks,
// tests/core/test_pipeline_real_injection_slow.cpp), so the search
// measures the spread where it searches: the statistic at random cells (positions, grid velocities) of the
// cube, by the search's own shifts, clipped at 3 sigma (a source on a random track is an outlier, not noise).
// It is a measurement for the user, not a correction: the SNRs and false-alarm probabilities stay the
// paper's. The core of the distribution does not give its 7-sigma tail: on the demo's cube (paper-neo, 500
// frames) the spread is 1.047 and the mean +0.32 (+0.0027 sigma_n per pixel left in the zero-biased frames,
// amplified ~6x by the matched filter and sqrt(N) by the sum), yet over 110 such cubes (seeds 21-130,
// 2026-12-05) the search found no false candidate at SNR >= 7, where Prob_false predicts 0.075 in all with
// the paper's unit and ~5 with (SNR - mean) / spread: the paper's trial count, every cell independent,
// absorbs the difference there.
#include <cstdint>
#include <string>

#include "st/search/types.hpp"

namespace st::search {

/// Random cells measured: about 1e7 frame samples in all, between 2,000 and 20,000 cells.
[[nodiscard]] int statisticNoiseCells(std::size_t frames) noexcept;

/// The statistic S / (sigma_F sqrt(N_in)) at statisticNoiseCells() random cells (x, y uniform over the image,
/// velocities uniform over `grid`'s cells; a fixed seed, so the same cube gives the same figure), those with
/// N_in >= minFrames kept; the standard deviation and mean after stats::sigmaClipSymmetric at 3 sigma,
/// the deviation corrected for the clip (/ 0.98658). Not measured (cells = 0) when sigma_F is not positive or
/// fewer than 1,000 cells keep N_in >= minFrames. Throws st::Cancelled.
[[nodiscard]] StatisticNoise measureStatisticNoise(const FilteredCube& cube, const VelocityGrid& grid,
                                                   int minFrames, CancelToken& cancel,
                                                   std::uint64_t seed = 1);

/// One line for the search's notes, e.g. "search statistic's noise on this cube: 1.074 +- 0.005 of the unit
/// sigma_F sqrt(N_in), mean -0.039 (20000 random cells, 3-sigma clipped; the paper's Prob_false assumes 1 and
/// 0)".
[[nodiscard]] std::string statisticNoiseNote(const StatisticNoise& noise);

}  // namespace st::search

#pragma once
// False-alarm probabilities of the velocity search (paper §4.5): the one-trial Gaussian tail
// Q(SNR) = erfc(SNR / sqrt 2) / 2, the detection false-alarm probability over the whole search
// (\label{Prob_false}: N_x N_y N_vx N_vy Q(SNR)), the confirmation false-alarm probability over the small
// window searched in a second observation (the equation after Prob_false), and the inverse: the SNR
// threshold that gives a target false-alarm probability. Pure arithmetic, careful for tiny probabilities
// (erfc, never 1 - erf; the inverse works in log space and past erfc's underflow).
#include <cstdint>

namespace st::stats {

/// One-sided Gaussian tail probability of one trial, Q(snr) = erfc(snr / sqrt 2) / 2. Exact to double
/// precision down to ~1e-308 (snr ~ 37.5); 0 beyond (use logTailProbability there).
double tailProbability(double snr);

/// ln Q(snr), finite for every snr (asymptotic series past erfc's underflow, relative error < 1e-12).
double logTailProbability(double snr);

/// The expected number of false alarms over `trials` independent trials at threshold `snr`:
/// trials * Q(snr). This is the paper's Prob_false before clamping (a union bound: it may exceed 1).
double expectedFalseAlarms(double snr, double trials);

/// Detection false-alarm probability, paper \label{Prob_false}:
/// P = N_x N_y N_vx N_vy * erfc(SNR / sqrt 2) / 2 with the actual trial counts, clamped to at most 1.
/// The paper's example: SNR 7, 512 x 512 pixels, 100 x 100 velocities -> 0.00335 (~0.34%).
double detectionFap(double snr, std::int64_t nx, std::int64_t ny, std::int64_t nvx, std::int64_t nvy);

/// Confirmation false-alarm probability (paper, the equation after Prob_false):
/// P = dN_x dN_y dN_vx dN_vy * erfc(SNR / sqrt 2) / 2, where the dN are the numbers of pixel positions and
/// grid velocities searched around the prediction from the first observation. Clamped to at most 1.
double confirmationFap(double snr, std::int64_t dnx, std::int64_t dny, std::int64_t dnvx, std::int64_t dnvy);

/// The SNR threshold at which `trials` * Q(snr) equals `targetFap` (the inverse of Prob_false).
/// targetFap must be in (0, trials / 2] and trials >= 1; throws st::InputError naming the value otherwise.
/// Solved in log space (bisection then Newton on ln Q), so targets like 1e-30 are exact; relative error of
/// the returned threshold < 1e-12.
double snrThresholdForFap(double targetFap, double trials);

}  // namespace st::stats

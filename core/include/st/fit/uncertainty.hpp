#pragma once
// The paper's closed-form precision and SNR formulas (Zhai et al. 2014, §3.2-3.3). Pure arithmetic, tested
// exactly against the formulas and, statistically, by the Monte Carlo of tests/core/test_fit_montecarlo*.
// Units: photons and pixels; sigma_n is the per-pixel noise standard deviation of one frame in the same
// units as the signal (photons when `nPhotons` is in photons).
#include <vector>

namespace st::fit {

/// Paper \label{detection_snr}: SNR = alpha sqrt(N_f) sqrt(sum P^2) / sigma_n, with alpha the PSF amplitude
/// per frame, `sumP2` the sum over pixels of P^2 (P with peak 1, pixelPsfSumOfSquares()), N_f the frames.
[[nodiscard]] double detectionSnr(double alpha, double frames, double sumP2, double sigmaN) noexcept;

/// The paper's approximation below detection_snr: SNR = 0.6 N_ph sqrt(N_f) / (sigma_n W), N_ph photons per
/// frame, W the FWHM in pixels.
[[nodiscard]] double detectionSnrApprox(double nPhotons, double frames, double sigmaN, double fwhm) noexcept;

/// Paper \label{eq:sig}: sigma_xy = sqrt(0.457 / N_ph + 1.37 sigma_n^2 W^2 / N_ph^2) W / sqrt(N_f), pixels;
/// N_ph photons per frame, W FWHM (pixels), sigma_n per-pixel noise (photons), N_f frames. Derived for a
/// Moffat PSF with beta ~ 4 (the first term is the photon noise, the second the background noise).
[[nodiscard]] double positionSigmaPaper(double nPhotons, double fwhm, double sigmaN, double frames) noexcept;

/// Paper \label{cent_snr}: sigma_xy ~ 0.65 W / SNR (background-limited approximation of eq:sig), pixels.
[[nodiscard]] double positionSigmaFromSnr(double fwhm, double snr) noexcept;

/// Paper \label{vel_snr}: sigma_v = sqrt(12) sigma_xy / T_tot, with T_tot the time covered by the frames
/// (seconds); sigma_v in pixels per second when sigma_xy is in pixels.
[[nodiscard]] double velocitySigma(double sigmaXY, double tTotS) noexcept;

/// The duration T_tot to use in vel_snr for frames at arbitrary times: sqrt(12 * mean((t_n - mean t)^2)),
/// seconds. For N evenly spaced frames at cadence dt this is dt sqrt(N^2 - 1) ~ N dt (the time the frames
/// cover), and with it vel_snr is exactly the least-squares velocity error given sigma_xy. 0 for < 2 frames.
[[nodiscard]] double effectiveDurationS(const std::vector<double>& timeOffsetsS) noexcept;

}  // namespace st::fit

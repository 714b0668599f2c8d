#pragma once
// Monte Carlo validation of the co-moving fit against the paper's precision formulas (§3.3, fig_snr):
// frames with a moving, pixel-integrated Moffat source (photon noise) plus Gaussian background noise are
// rendered here, independently of the simulator, fitted, and the scatter of the fitted positions and
// velocities is compared with eq:sig and vel_snr. Used by tests/core/test_fit_montecarlo*.cpp and by
// `synthtrack-cli bench fit --montecarlo` (which writes the fig_snr-like table and plot).
#include <cstdint>
#include <vector>

#include "st/common/frame_cube.hpp"
#include "st/common/progress.hpp"
#include "st/common/units.hpp"
#include "st/psf/moffat.hpp"

namespace st::fit {

/// A moving point source, for rendering.
struct MovingSource {
  double x = 0.0;        ///< column at t_ref (the cube's mean time)
  double y = 0.0;        ///< row at t_ref
  Velocity v;            ///< px/s
  double photons = 0.0;  ///< expected photons per frame (the PSF's total over the plane)
};

/// Fills every frame of `cube` (sizes and times already set) with the expected photons of `source`,
/// integrated over each pixel by 5x5 sub-sampling (a finer rule than the fitter's 3x3, on purpose), out
/// to ceil(4 W) + 4 px from the source (the tail beyond holds < 1e-4 of the flux for R = 3.3, beta = 4).
/// Adds to what is there.
void renderMovingSource(FrameCube& cube, const psf::Moffat& psf, const MovingSource& source);

/// A cube of `frames` frames of size x size px at a constant cadence (mid-times from MJD 60000).
[[nodiscard]] FrameCube makeEmptyCube(int size, int frames, double cadenceS);

/// Replaces every pixel by a Poisson draw of its value (photon noise; values <= 0 give 0) plus a Gaussian
/// of standard deviation sigmaN (background); the frames are then zero-biased with noise sigma_n.
void addNoise(FrameCube& cube, double sigmaN, bool photonNoise, std::uint64_t seed);

struct MonteCarloConfig {
  psf::Moffat psf{3.3, 4.0};  ///< paper §3.3: R ~ 3.3, beta ~ 4
  int frames = 50;
  double cadenceS = 0.06;  ///< CHIMERA at 16.7 Hz
  int size = 48;           ///< frame side, px
  Velocity v{2.0, -1.0};   ///< px/s
  double photonsPerFrame = 1000.0;
  double sigmaN = 1.0;  ///< per-pixel background noise, photons
  bool photonNoise = true;
  int trials = 100;
  int stampHalfSize = 0;  ///< 0: the fit's default (ceil(3 W))
  std::uint64_t seed = 1;
};

struct MonteCarloPoint {
  MonteCarloConfig config;
  int converged = 0;              ///< trials whose fit converged (the statistics use these)
  double meanDx = 0, meanDy = 0;  ///< mean fitted - true position, px
  double sdX = 0, sdY = 0;        ///< standard deviation of the fitted positions, px
  double sdPos = 0;               ///< sqrt((sdX^2 + sdY^2) / 2)
  double meanDvx = 0, meanDvy = 0;
  double sdVx = 0, sdVy = 0;       ///< px/s
  double sdVel = 0;                ///< sqrt((sdVx^2 + sdVy^2) / 2)
  double meanSnr = 0;              ///< mean detection_snr of the fits (with the true sigma_n)
  double meanPhotons = 0;          ///< mean fitted photons per frame
  double meanHessianSigmaPos = 0;  ///< mean Hessian position error (x and y averaged), px
  double predictedSigmaPos = 0;    ///< eq:sig for the true N_ph, W, sigma_n, N_f
  double predictedSigmaVel = 0;    ///< vel_snr from predictedSigmaPos and effectiveDurationS
  double predictedSnr = 0;         ///< detection_snr for the true alpha
};

/// Runs `config.trials` independent render+fit trials (source at a random sub-pixel position near the
/// frame centre; the fit starts at the rounded position and a velocity off by 0.2 px over the span, like a
/// search cell). Deterministic for a given seed. Polls `cancel` between trials.
[[nodiscard]] MonteCarloPoint runMonteCarlo(const MonteCarloConfig& config, CancelToken& cancel);

}  // namespace st::fit

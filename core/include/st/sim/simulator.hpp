#pragma once
// The observation simulator (issue 2, section 5): synthetic frame cubes with a truth record, deterministic
// from a seed, so that every later stage can be scored against what was put in.
//
// Detector model, per pixel and frame (all "photons" are detected photons = photo-electrons; the QE is
// folded into the zero point):
//   lambda   = flat(x, y) * (sky + stars + objects)                     expected photo-electrons
//   n        = Poisson(lambda), then column bleed above fullWellE        image-area charge
//   e_out    = Gamma(n, emGain) when emGain > 1 (else n)                 EM register, excess factor sqrt(2)
//   raw_ADU  = bias(x, y) + e_out / gainEPerAdu + Normal(0, readNoiseE / gainEPerAdu) + hot + cosmic rays
//   raw_ADU  clipped to [0, saturationAdu] (ADC full scale)
// Hot pixels (a fixed excess in ADU every frame) and cosmic rays (1 to 5 px, one frame, ADU) are added after
// the EM register; both are listed in the truth. Diffraction spikes are four arms along +-x and +-y.
// The bleed is modelled in the image area with an effective full well; in an EMCCD the EM register and
// the ADC saturate first, so the EM presets set fullWellE near that limit (a documented simplification).
// Poisson and Gamma are sampled exactly (st/sim/samplers.hpp); noiseless = true keeps the expected values.
// The Gamma(n, G) output of an EM register of gain G is the standard high-gain model (Basden et al. 2003):
// its variance is 2 n G^2, i.e. the sqrt(2) excess noise factor, with the real, skewed output distribution.
// A calibrated frame (raw - bias) / flat therefore has signal photons * emGain / gainEPerAdu ADU.
//
// Geometry and time follow ARCHITECTURE.md: 0-based pixels, centres at integers; frame n has its exposure
// mid-time t_n; t_ref = mean of the t_n; a source at t is at x(t) = x_ref + vx (t - t_ref). Every source is
// trailed over its exposure (sub-stepped, <= 0.1 px), since the paper's sky drift of 5"/s moves stars ~1 px
// in 60 ms; moving objects are trailed with their own velocity in the frames (sky drift + own motion), so
// in paper-neo they trail ~0.9 px too. The PSF is integrated over pixels (8x8 sub-samples, tabulated at 1/8
// px phases and interpolated) and each source's total flux is exact up to clipping at the frame edges.
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "st/calib/calibration.hpp"
#include "st/common/frame_cube.hpp"
#include "st/common/image.hpp"
#include "st/common/progress.hpp"
#include "st/psf/moffat.hpp"
#include "st/search/demo_grid.hpp"
#include "st/sim/truth.hpp"

namespace st::sim {

/// The paper's photometric calibration (§5.1): a V = 9.1 star gives 8.1e7 photons/s at the detector.
inline constexpr double kPaperCalMag = 9.1;
inline constexpr double kPaperCalPhotonsPerS = 8.1e7;
/// Photons/s of a magnitude-0 source under that calibration: 8.1e7 * 10^(0.4 * 9.1) = 3.54e11.
double paperZeroPointPhotonsPerS();

/// A linearly moving object. Its motion is given relative to the star field (the sky); its velocity in the
/// frames is that plus the sky drift (SimParams::skyDriftXPxPerS/Y), which is what the truth reports as
/// vx_px_s / vy_px_s.
struct MovingObject {
  std::string name = "obj1";
  double xRefPx = 0.0;       ///< x at t_ref, 0-based pixels (frame coordinates)
  double yRefPx = 0.0;       ///< y at t_ref
  double skyVxPxPerS = 0.0;  ///< motion relative to the stars, px/s along x
  double skyVyPxPerS = 0.0;  ///< motion relative to the stars, px/s along y
  double magnitude = 20.0;   ///< apparent magnitude (same system as SimParams::zeroPointPhotonsPerS)

  /// Builds an object from a rate in deg/day and a direction in degrees (0 = +x, 90 = +y), relative to
  /// the stars, using the plate scale in arcsec/px.
  static MovingObject fromRate(std::string name, double xRefPx, double yRefPx, double rateDegPerDay,
                               double directionDeg, double magnitude, double plateScaleArcsecPerPx);
};

/// A star placed by hand (e.g. the reference star of "known-pair", or an isolated star for a test).
struct FixedStar {
  double xRefPx = 0.0;  ///< at t_ref, 0-based; moves with the sky drift
  double yRefPx = 0.0;
  double magnitude = 15.0;
};

/// Every knob of a simulated observation. Defaults are a modest conventional CCD; presets set the rest.
struct SimParams {
  // Geometry and timing.
  int width = 128;
  int height = 128;
  int frames = 64;
  double frameRateHz = 10.0;  ///< frames per second; frame n starts at n / frameRateHz
  double exposureS = 0.09;    ///< exposure length, s (<= 1 / frameRateHz)
  double startMjd = 56546.3;  ///< start of the first exposure, MJD (UTC)
  double plateScaleArcsecPerPx = 0.305;
  double raDeg = 350.0;  ///< sky position of the frame centre at the first frame (TAN WCS)
  double decDeg = -5.0;

  // Optics and sky.
  psf::Moffat psf{3.3, 4.0};  ///< R px, beta (paper §3.3)
  double skyPhotonsPerPxPerFrame = 50.0;
  double skyDriftXPxPerS = 0.0;  ///< motion of the whole star field in the frames, px/s
  double skyDriftYPxPerS = 0.0;

  // Detector.
  double readNoiseE = 5.0;            ///< read noise at the output amplifier, e- rms
  double gainEPerAdu = 2.0;           ///< output e- per ADU
  double emGain = 1.0;                ///< EMCCD multiplication gain; 1 = conventional CCD (no excess noise)
  double biasLevelAdu = 500.0;        ///< mean bias level
  double biasColumnPatternAdu = 2.0;  ///< rms of a fixed column-to-column bias pattern
  double flatAmplitude = 0.02;        ///< rms of the pixel-to-pixel flat pattern (plus a 3% vignetting)
  double fullWellE = 60000.0;         ///< image-area full well, photo-electrons; excess bleeds along columns
  double saturationAdu = 65535.0;     ///< ADC full scale of raw frames
  bool noiseless = false;             ///< expected values only: no Poisson, EM, read noise (tests)

  // Photometry and stars.
  double zeroPointPhotonsPerS = 3.54e11;  ///< photons/s of a magnitude-0 source (paperZeroPointPhotonsPerS)
  int starCount = 20;                     ///< mean number of stars inside the frame at any time
  double starMagMin = 14.0;               ///< brightest star magnitude
  double starMagMax = 22.0;          ///< faintest star magnitude; N(<m) proportional to 10^(0.3 m) between
  double spikeMagLimit = 15.0;       ///< stars brighter than this get diffraction spikes
  double spikeFraction = 0.01;       ///< fraction of such a star's photons in its four spikes
  double starMinSeparationPx = 0.0;  ///< keep stars at least this far from any moving object at all times
  int brightStars = 0;               ///< extra bright stars (saturated, spiked) placed to cross the frame,
  double brightStarMagMin = 10.0;    ///< uniform in [min, max] magnitude, >= 40 px from object paths
  double brightStarMagMax = 11.0;

  // Artefacts.
  double cosmicRaysPerFrame = 0.5;  ///< mean number of single-frame cosmic-ray hits per frame (Poisson)
  double cosmicRayMinAdu = 300.0;   ///< peak amplitude range of a hit, ADU above the frame
  double cosmicRayMaxAdu = 5000.0;
  int hotPixels = 10;            ///< number of hot pixels (fixed across frames)
  double hotPixelMinAdu = 50.0;  ///< excess of a hot pixel per frame, ADU
  double hotPixelMaxAdu = 2000.0;

  std::vector<FixedStar> fixedStars;  ///< drawn in addition to the random ones, listed first in the truth
  std::vector<MovingObject> objects;

  // Provenance.
  std::string presetName = "custom";

  /// Throws st::InputError naming the first bad value (non-positive sizes, exposure > frame period, ...).
  void validate() const;
};

/// The simulated observation and what was put in it.
struct SimResult {
  FrameCube cube;   ///< raw frames in ADU, float32, FrameInfo with mid-times, header with WCS
  Truth truth;      ///< what the frames contain (st/sim/truth.hpp)
  Image biasFrame;  ///< the exact (noise-free) bias pattern used, ADU
  Image flatFrame;  ///< the exact flat pattern used, mean 1
};

/// The master calibration that undoes the simulated bias and flat exactly (no calibration-frame noise), for
/// pre-processing a simulated cube as if perfect masters had been taken.
calib::MasterCalibration exactMasters(const SimResult& result);

/// Simulates an observation. Deterministic: the same params and seed give identical pixels, for any
/// number of threads (each frame has its own RNG stream). Frames are generated in parallel with
/// st::parallelFor; progress is reported per frame; cancel throws st::Cancelled. Throws st::InputError for
/// invalid params.
SimResult simulate(const SimParams& params, std::uint64_t seed, ProgressSink& progress, CancelToken& cancel);

/// The truth of simulate(params, seed) without rendering any frame (fast: plans the scene and computes the
/// expected SNRs). Used by the presets to tune SNRs, and by tests.
Truth predictTruth(const SimParams& params, std::uint64_t seed);

/// Individual raw calibration frames matching a simulation with the same params and seed: `nBias` bias
/// frames (bias pattern + read noise) and `nFlat` flat frames (bias + flat * flatLevelE photo-electrons,
/// with Poisson and read noise, no EM gain). For testing the calibration stage end to end.
struct CalibrationFrames {
  std::vector<Image> bias;
  std::vector<Image> flat;
};
CalibrationFrames simulateCalibrationFrames(const SimParams& params, std::uint64_t seed, int nBias, int nFlat,
                                            double flatLevelE = 20000.0);

/// Named presets. Throws st::InputError listing the valid names for any other name.
///  - "paper-neo": the paper's detection (Zhai et al. 2014, §1, §4.1, §5.1): 512x512 px at 0.305"/px,
///    EMCCD (EM gain 200) at 16.7 Hz, 500 frames (~30 s), sky drifting at 5"/s along +x (drift scan), one
///    V = 23.1 asteroid (the paper's 6300 photons in 30 s under its 9.1 mag <-> 8.1e7 photons/s calibration)
///    at 5.97 deg/day, 150 deg from +x (30 deg off the scan axis, against the scan like the paper's
///    [-5.97, 0.09] deg/day). The sky level is tuned so that the truth's expected matched-filter SNR is 15;
///    in a stack tracking the stars the object is a ~23 px streak with SNR ~3-4.
///  - "known-pair": the paper's §2 data (2009 BL2): 2 Hz, 0.5 s frames, 960 frames, sidereal tracking,
///    256x256, a V = 16 star and a V = 18.5 asteroid at 0.6 deg/day (a streak of ~40 px in 8 min, so the
///    trailing loss is of the ~2.3 mag the paper shows).
///  - "small": 128x128, 64 frames at 10 Hz, conventional CCD, no drift, 5 faint stars kept >= 15 px from
///    the object, one saturated star with spikes and bleed, cosmic rays and hot pixels, one object at 4
///    px/s whose magnitude is tuned to an expected SNR of 20. Fast: for tests.
SimParams preset(std::string_view name);
/// The valid preset names.
std::vector<std::string> presetNames();

/// The demo's search grid (st/search/demo_grid.hpp, where the pipeline and the GUI read it): +-8 deg/day
/// around the sky rate in steps of 1.5 px over the time span.
using search::kDemoGridStepPx;
using search::kDemoHalfRangeDegPerDay;

/// The demo's half-range for preset `name`, deg/day around the sky rate: enough to reach its objects with
/// margin and small enough to search in seconds: paper-neo 8 (object at 5.97 deg/day), known-pair 1.5
/// (0.6 deg/day over a 480 s span, where +-8 deg/day would be ~7e5 velocities), small 40 (29 deg/day).
/// Throws st::InputError for an unknown preset.
double presetDemoHalfRangeDegPerDay(std::string_view name);

/// Changes the number of frames and/or the frame size of a preset, keeping moving objects at the same
/// place relative to the frame centre and the star density. Non-positive values leave that unchanged.
void resize(SimParams& params, int width, int height, int frames);

}  // namespace st::sim

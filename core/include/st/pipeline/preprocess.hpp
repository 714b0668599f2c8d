#pragma once
// Pre-processing of one observation (paper §4.2-4.3, ARCHITECTURE.md data flow):
//   calibrate (overscan, bias, dark, flat, trim, bad pixels)
//   -> each frame's own smooth background (SEP mesh) removed, the cube's median sky level kept
//   -> registration: each frame's star-field offset, chained frame to frame; the linear sky rate when it
//      fits, else per-frame offsets o_n (FrameInfo) that every later stage and the search use
//   -> global background (50 frames, xi = 5) and sky rate (given, or measured from the stars)
//   -> cosmic rays (stars protected by sky-rate stacks; hits filled from their time neighbours for now)
//   -> static sources in the sky-rate stack (SNR >= 7 per pixel or after the PSF filter; wings, spikes and
//      bleed trails of saturated stars): star catalog and footprint mask; sources whose centroid moves
//      between the stacks of the first and last thirds of the frames are movers, left unmasked
//   -> per-pixel background (<= 2000 frames, xi = 4, stars left out), sigma_n, subtraction (zero-biased)
//   -> cosmic-ray pixels, static sources (along the sky motion), pixels without a measured background and
//      single-frame sources (SNR >= 7) zeroed, the movers' tracks spared
//   -> PSF (Moffat fit on the sky-rate stack of the zero-biased frames, before zeroing)
//   -> each frame's residual local mean removed, the noise model (s_n^2 v(q)) measured
//   -> the inverse-variance-weighted matched filter (stats/noise_model.hpp, stack/matched_filter.hpp).
//
// Memory: the raw cube is taken by value and becomes the zero-biased cube in place; the only extra full
// cube is the matched-filtered copy (Prepared::filtered), none when !keepZeroBiased (filtered in place).
// Per-pixel images (background, noise), the stacks and masks are frame-sized; the cube's pixel mask (1 byte
// per sample, a quarter of a float cube) exists only when the loader or the bad-pixel mask needs one.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "st/calib/calibration.hpp"
#include "st/calib/cosmic_rays.hpp"
#include "st/common/frame_cube.hpp"
#include "st/common/image.hpp"
#include "st/common/progress.hpp"
#include "st/detect/registration.hpp"
#include "st/detect/sky_rate.hpp"
#include "st/detect/static_sources.hpp"
#include "st/detect/star_subtraction.hpp"
#include "st/psf/moffat.hpp"
#include "st/search/types.hpp"
#include "st/stats/background.hpp"
#include "st/stats/noise_model.hpp"

namespace st::pipeline {

class PreprocessAccelerator;

struct PreprocessParams {
  std::optional<calib::MasterCalibration> masters;  ///< from calib::buildMasters; none = overscan/trim only
  calib::CalibParams calib;
  bool findHotPixels = true;  ///< mask pixels bright in every block of frames and sharper than the PSF
  bool removeCosmicRays = true;
  calib::CosmicRayParams cosmicRays;   ///< skyRate and fill are set by the pipeline
  stats::BackgroundParams background;  ///< paper: global 50 frames xi 5, per-pixel <= 2000 frames xi 4
  std::optional<Velocity> skyRate;     ///< px/s; none = measure it from the stars
  detect::SkyRateParams skyRateParams;
  /// Per-frame registration (pipeline/registration_stage.hpp): offsets of the star field beyond the linear
  /// sky rate (dithers, guiding, re-pointing), used by every later stage and the search. On by default:
  /// a smoothly drifting or tracked field keeps the linear model (test_registration's drifting EMCCD cube);
  /// CLI --no-register turns it off.
  bool registerFrames = true;
  detect::RegistrationParams registration;
  /// A registration measured before (on another region of the same frames: out-of-core pre-processing,
  /// preprocess_out_of_core.hpp): applied as it is instead of measured. Wins over registerFrames.
  std::optional<detect::Registration> givenRegistration;
  detect::StaticSourceParams stars;  ///< paper §4.3: SNR 7
  double singleFrameSnr = 7.0;       ///< paper §4.3: bright objects in single frames, SNR 7
  double psfFwhmPx = 3.0;            ///< footprint dilation before the fit, and the fallback PSF
  double psfBeta = 4.0;              ///< beta of the fallback PSF (paper §3.3)
  std::optional<std::pair<double, double>>
      psfStar;  ///< the star the user names for the PSF (0-based px, t_ref)
  /// The PSF measured before (out-of-core pre-processing: on the reference region): used as it is, no PSF
  /// fit, and the static sources' footprints drawn at its FWHM from the start.
  std::optional<psf::Moffat> givenPsf;
  bool matchedFilter = true;  ///< produce Prepared::filtered (one extra cube)
  /// Keep the zero-biased cube (Prepared::frames) beside the filtered one. False: the matched filter runs
  /// in place on it (one cube less at the peak; Prepared::frames is left empty), for a search without fits.
  bool keepZeroBiased = true;
  /// With an accelerator: stacks at the sky rate made on threads of their own ahead of their use (the cosmic
  /// rays' protection beside the wait for the frames' download, the static sources' thirds and halves beside
  /// their analysis). The same stacks either way (false: each made when asked, for comparison).
  bool stacksAhead = true;
  stats::FrameBackgroundParams frameBackground;  ///< each frame's smooth background (SEP), before all else
  bool removeResidualMean = true;  ///< remove each zero-biased frame's residual local mean (mesh)
  int residualMeshPx = 64;         ///< its mesh cell
  /// Drifting fields: the stars' sky-registered template subtraction (stars.subtractStars turns it off).
  detect::StarSubtractionParams starSubtraction;
  bool weightedFilter = true;  ///< inverse-variance-weighted matched filter (else the paper's uniform one)
  stats::NoiseModelParams noise;
  /// Runs the per-pixel background and the matched filter on a device (preprocess_accelerator.hpp); null =
  /// the CPU. Not owned. A device failure falls back to the CPU with a note.
  PreprocessAccelerator* accelerator = nullptr;
};

struct Prepared {
  FrameCube frames;         ///< zero-biased; cosmic rays, stars, single-frame sources and masked pixels 0
  double sigmaN = 0.0;      ///< noise of one pixel of one frame, counts (paper §4.2)
  Image background;         ///< per-pixel background that was subtracted, counts
  /// Which frames went into each frame's per-pixel background: what the co-moving fit's model takes of a
  /// mover's own flux (fit::FitOptions::selfSubtraction; candidate::fitCandidate). Empty: not recorded.
  stats::PixelBackgroundWindows backgroundWindows;
  Image noise;              ///< per-pixel frame-to-frame sigma, counts
  Image noiseMap;           ///< smooth noise map when params.background.noiseMap
  stats::ClipStats global;  ///< pixel-independent background (50 frames, xi = 5)
  std::vector<detect::Star> stars;  ///< static-source catalog, positions at t_ref
  /// Sources of the sky-rate stack that moved between its first and last thirds (slow moving objects): not
  /// masked, not zeroed as single-frame sources, left for the search
  /// (detect::StaticSourceParams::keepMovers).
  std::vector<detect::MovingSource> movers;
  Velocity skyRate;  ///< px/s
  bool skyRateMeasured = false;
  /// How the sky rate was measured (chained or not, the blocks' residual rms) when detect::measureSkyRate
  /// ran; left default when the rate was given or came from registration.
  detect::SkyRate skyRateMeasurement;
  /// The registration measured (model, rate, rms); the offsets themselves are in frames.info().
  detect::Registration registration;
  calib::CalibrationReport calibration;
  std::size_t hotPixels = 0;  ///< found in the science frames and masked in every frame
  std::vector<std::size_t> cosmicRaysPerFrame;
  std::size_t cosmicRays = 0;
  std::size_t staticPixelsZeroed = 0;  ///< over all frames
  /// Pixels (each counted once) whose background could not be measured, not on a mover's track, that were
  /// not already 0 in every frame: zeroed in every frame (detect::zeroUnmeasured).
  std::size_t unmeasuredPixelsZeroed = 0;
  detect::SingleFrameSources singleFrame;
  psf::Moffat psf;  ///< fitted, or the fallback of params.psfFwhmPx
  bool psfFitted = false;
  std::optional<std::pair<double, double>> psfStarAt;  ///< the star used (0-based px at t_ref)
  search::FilteredCube filtered;                       ///< matched-filtered frames and sigma_F for the search
  std::vector<std::string> notes;              ///< what the user should know (sky rate, PSF fallback, ...)
  std::vector<std::uint64_t> cosmicRayPixels;  ///< flat cube indices of the pixels zeroed as cosmic rays
  stats::FrameBackgrounds frameBackgrounds;    ///< each frame's SEP level and rms (before all else)
  detect::StarSubtraction starSubtraction;     ///< drifting fields: what the star template removed
  double residualMeanRms = 0.0;                ///< rms of the residual local means removed, counts
  stats::NoiseModel noiseModel;  ///< variance s_n^2 v(q) used by the weighted filter (empty when off)
  std::vector<std::pair<std::string, double>> stageSeconds;  ///< wall time of each stage
  /// The process's CPU seconds in each stage up to the per-pixel background (the host's stages; their
  /// ratio to the wall time tells how many cores a stage kept busy), by stage name.
  std::vector<std::pair<std::string, double>> stageCpuSeconds;
  double elapsedS = 0.0;
};

/// Runs the whole pre-processing on `raw` (moved in; it becomes Prepared::frames). Throws st::InputError on
/// bad input (sizes, all masked, ...), st::Cancelled when cancelled. Progress goes from 0 to 1 over stages.
Prepared preprocess(FrameCube raw, const PreprocessParams& params, ProgressSink& progress,
                    CancelToken& cancel);

}  // namespace st::pipeline

#pragma once
// Cosmic rays (paper §4.2): "Cosmic ray events are detected by first zeroing out the bright stars ... We
// differentiate the bright stars from the cosmic ray events by integrating over hundreds of frames ... After
// zeroing the signals from the bright stars, differences between consecutive frames are used to identify
// highly varying signals on the frame-to-frame basis." Here stars are protected (not zeroed) by a mask made
// from stacks at the sky rate; a pixel is a hit when it stands above both of its neighbours in time, taken
// both at the same detector pixel (hot pixels, bad columns) and at the same place on the sky (integer shifts
// at the sky rate, so that a star drifting by ~1 px per frame is compared with itself, not with its wing).
//
// The threshold follows the noise that is actually there. A threshold in units of a Gaussian-equivalent
// sigma flags far too many pixels when the noise has a heavy right tail (an EMCCD's gain register gives an
// exponential excess; Poisson counts are skewed at low levels): an excess of 7 "sigma" over both neighbours
// has probability 1.2e-9 for Gaussian noise but 1.7e-5 per pixel on the paper-neo sky (~3.6 photons per pixel
// through an EM gain of 200; measured on 5e7 noise-only pixels). So the excess E = F_n - max(two nearest
// frames, both registrations) of noise-only pixels is measured on the cube itself, its upper tail is fitted
// by an exponential between the 1e-2 and 1e-3 exceedance quantiles, and the seed threshold is where that tail
// reaches CosmicRayParams::falseFlagRate. Tails that fall faster than exponential (Gaussian, Gamma, the EMCCD
// compound Poisson-Gamma whose log-slope steepens towards -1/gain) are over-estimated by the exponential, so
// the false-flag rate is at most the target (checked in tests/core/test_calib_emccd.cpp). Hits themselves
// must stay well below 1e-3 of the pixels (paper-neo: ~5e-7), or they lift the measured tail and the
// threshold with it.
#include <cstddef>
#include <cmath>
#include <cstdint>
#include <functional>
#include <optional>
#include <vector>

#include "st/common/timed_parts.hpp"
#include "st/common/frame_cube.hpp"
#include "st/common/progress.hpp"
#include "st/common/units.hpp"
#include "st/detect/sky_stack.hpp"

namespace st::calib {

/// Exponential model of the upper tail of the excess E = F_n - max(two nearest frames, both registrations) of
/// noise-only pixels: P(E > t) = 1e-3 exp(-(t - at1e3) / scale) for t >= at1e3.
struct TailModel {
  static constexpr std::size_t kMinSamples = 20000;  ///< fewer samples: no model (threshold() = 0)
  double at1e2 = 0.0;                                ///< E exceeded by 1e-2 of the samples, counts
  double at1e3 = 0.0;                                ///< E exceeded by 1e-3 of the samples, counts
  double scale = 0.0;  ///< e-folding of the tail, (at1e3 - at1e2) / ln 10, counts
  std::size_t samples = 0;
  /// E exceeded with probability p (< 1e-3) under the model, counts; 0 without a model.
  [[nodiscard]] double threshold(double p) const noexcept {
    return samples < kMinSamples ? 0.0 : at1e3 + scale * std::log(1e-3 / p);
  }
};

/// Measures the TailModel on up to 8 frames spread over the cube: all their unmasked pixels (x, y) of frame
/// n that `skip(n, x, y)` does not exclude (e.g. protected stars), with the reference frames registered at
/// `skyRate` (px/s, integer shifts round(v (t_n - t_ref)) as in the sky-rate stack).
TailModel fitExcessTail(const FrameCube& cube, Velocity skyRate,
                        const std::function<bool(std::size_t, int, int)>& skip = {});

struct CosmicRayParams {
  double thresholdSigma = 7.0;  ///< hit: F_n - max(references) > thresholdSigma * sigma (one frame)
                                ///< and above the tail threshold at falseFlagRate, whichever is higher
  double falseFlagRate = 1e-7;  ///< target probability that a noise-only pixel seeds a hit (see above)
  double growSigma = 5.0;       ///< 8-neighbours of a hit above this join it (tracks, charge spread) ...
  double growFalseRate = 1e-4;  ///< ... and above the tail threshold at this rate, whichever is higher
  double protectSnr = 5.0;      ///< pixels whose SNR is >= this in every one of `protectBlocks` sky-rate
                                ///< stacks that observe them (>= 10% of the block's frames, >= 3) are
                                ///< protected (a star is in every block that sees it, a hit in one)
  int protectBlocks = 3;
  int protectDilatePx = 2;
  double protectedExcess = 1.0;  ///< on a protected pixel a hit must also exceed this times the star signal
  /// A seed whose 3 x 3 neighbourhood in its own frame has a median (above the median of the 5 x 5 ring
  /// around it) of at least sourceMedianLow and at most sourceMedianHigh times its own value (above that
  /// ring), and at least sourceMedianSigma * sigma, is the core of a source that the PSF resolves, not a hit:
  /// a bright slow mover, which stands above the same pixel of its time neighbours in every frame and is not
  /// a protected static star (5945 on the Lowell frames lost 2-10 core pixels per frame, and a dithered
  /// run's different flags cost it 10% of its SNR). A hit is sharper: a single pixel, a pair or a track of
  /// width 1 covers at most 3 of the 9 pixels (median ~0); a flat splotch has a ratio near 1. A point source
  /// centred on a pixel has ratio ~0.2 at FWHM 1.3 px, 0.29 at 1.5, 0.5 at 2. 0 = off (every seed is a hit).
  double sourceMedianLow = 0.15;
  double sourceMedianHigh = 0.8;
  double sourceMedianSigma = 3.0;
  Velocity skyRate;  ///< px/s, so that protection follows drifting stars
  /// Calibrated counts at which pixels saturate (pre-processing derives it from SATURATE or BITPIX). When
  /// set, a pixel within bleedReachPx rows of a pixel of its own column at or above bleedFraction of it in
  /// the same frame is not a hit: the tip of a saturated star's bleed column moves by a pixel or two from
  /// frame to frame with the star's photon noise (paper-neo: most false flags sat 12 and 18 px along the
  /// column of a saturated star, next to its bleed at the full well, 60,000 ADU where SATURATE says 65,535).
  std::optional<double> saturationLevel;
  int bleedReachPx = 2;
  double bleedFraction = 0.8;
  enum class Fill { Zero, TimeNeighbours };
  /// Zero (the paper) for zero-biased frames; TimeNeighbours (mean of the two frames used as reference) when
  /// the background has not been subtracted yet, so that the per-pixel clip is not pulled down. The pipeline
  /// uses TimeNeighbours and zeroes the listed pixels after background subtraction.
  Fill fill = Fill::Zero;
};

struct CosmicRayResult {
  std::vector<std::size_t> perFrame;  ///< pixels flagged in each frame
  std::size_t total = 0;
  std::vector<std::uint64_t> pixels;  ///< flat indices n * width * height + y * width + x, sorted
  std::size_t sourceSeeds = 0;  ///< seeds set aside as resolved sources (CosmicRayParams::sourceMedianLow)
  std::size_t protectedPixels = 0;   ///< reference positions protected as stars
  int protectionStacks = 0;          ///< stacks at the sky rate the protection used (protectBlocks)
  int protectionStacksProvided = 0;  ///< of them, made by removeCosmicRays' provider (a device)
  bool preTestProvided = false;      ///< the seeds' pre-test came from removeCosmicRays' preTest
  double sigma = 0.0;                ///< single-frame noise from frame differences, counts
  TailModel tail;                    ///< the measured tail of the excess
  double seedThreshold = 0.0;        ///< excess a seed had to exceed, counts
  double growThreshold = 0.0;        ///< excess a grown neighbour had to exceed, counts
  /// Wall time of the parts, for the notes: the noise from frame differences, the protection (and of it, its
  /// stacks at the sky rate), the excess tail, the seeds (pass 1), growing and filling.
  TimedParts parts;
};

/// The seeds' cheap pre-test of every pixel of a cube of >= 3 frames: bit j of word w is set for flat index
/// k = 32 w + j (k = n * width * height + y * width + x) where !(f - max(fa, fb) <= thr) in float arithmetic
/// (NaN passes), f the pixel, fa and fb the same pixel of frame n's two reference frames (its neighbours;
/// frames 1 and 2 for the first, the two before it for the last), max as std::max(fa, fb). Only the
/// non-zero words, in strictly ascending w (a few per frame: noise passes at ~1e-4); words out of order or
/// repeated are not used.
struct CosmicRayPreTestWords {
  std::vector<std::uint64_t> index;  ///< w
  std::vector<std::uint32_t> bits;   ///< word w
  friend bool operator==(const CosmicRayPreTestWords&, const CosmicRayPreTestWords&) = default;
};
/// The pre-test made elsewhere (a device holding the cube, issue 16); none: not made there.
using CosmicRayPreTest =
    std::function<std::optional<CosmicRayPreTestWords>(const FrameCube& cube, float thr)>;

/// That pre-test on the CPU (the reference the device's is tested against).
CosmicRayPreTestWords cosmicRayPreTestWords(const FrameCube& cube, float thr);

/// The frame ranges whose stacks at the sky rate (nothing subtracted) the protection asks for, for a cube of
/// `frames` frames and `protectBlocks` blocks: made ahead elsewhere, they are the same stacks.
std::vector<detect::SkyStackCache::Range> protectionRanges(std::size_t frames, int protectBlocks);

/// Finds and removes cosmic-ray hits in place. Needs >= 3 frames (fewer: nothing is done, total 0).
/// Masked pixels are never flagged. The protection's stacks at the sky rate come from `stacks` when given
/// and it makes them (a device holding the cube, issue 16: the same sums), else from the CPU; so does the
/// seeds' pre-test from `preTest` (the same pixels pass). Throws st::Cancelled.
CosmicRayResult removeCosmicRays(FrameCube& cube, const CosmicRayParams& params, ProgressSink& progress,
                                 CancelToken& cancel, const detect::SkyStackCache::Provider* stacks = nullptr,
                                 const CosmicRayPreTest* preTest = nullptr);

/// Sets the listed pixels (flat cube indices) to 0.
void zeroPixels(FrameCube& cube, const std::vector<std::uint64_t>& pixels);

/// Single-frame noise from differences of frame pairs (symmetric clip, xi = 5, / sqrt 2), unmasked pixels.
double noiseFromFrameDifferences(const FrameCube& cube);

}  // namespace st::calib

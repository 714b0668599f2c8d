#pragma once
// Static sources (paper §4.3): stars and galaxies found in the stack at the sky rate (SNR >= 7 per pixel, or
// after the PSF filter, i.e. as the velocity search would see them; with the number of contributing frames
// N_in so that stars entering or leaving the drifting field are found too) and bright objects found in
// single frames (SNR >= 7), zeroed in every frame with their footprint dilated by the PSF and carried along
// with the sky motion. Saturated stars also lose their Moffat wings (radius growing with the flux),
// diffraction spikes and column bleed trails (charge leakage), measured in the stack: the paper's main false
// positives. The star catalog (position, flux, saturated, bleed columns) is kept for astrometry and vetting.
// A source whose centroid moves between the stacks of the first and last thirds of the frames (a slow moving
// object, a short streak that looks like a star) is not static: it is listed as a mover and left unmasked.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <utility>
#include <vector>

#include "st/common/timed_parts.hpp"
#include "st/common/frame_cube.hpp"
#include "st/common/image.hpp"
#include "st/common/progress.hpp"
#include "st/common/units.hpp"
#include "st/detect/moving_mask.hpp"
#include "st/detect/sky_stack.hpp"

namespace st::detect {

struct StaticSourceParams {
  double snrThreshold = 7.0;  ///< detection in the sky-rate stack (paper §4.3: SNR 7)
  double growSnr = 2.0;       ///< a detection's footprint grows over connected pixels down to this SNR
  double psfFwhmPx = 3.0;     ///< PSF FWHM used for the dilation before the PSF is fitted (paper: ~3 px)
  double dilateFwhm = 1.0;    ///< footprints are dilated by ceil(dilateFwhm * FWHM) + 1 px (sub-pixel motion)
  int meshPx = 32;            ///< cell of the local background of the stack
  std::optional<double> saturationLevel;  ///< calibrated counts; else a flat-topped peak counts as saturated
  /// Also detect (and grow) in the stack filtered by a Moffat of psfFwhmPx: the search's matched filter
  /// lifts stars that are below snrThreshold per pixel above it (N_in counted at the edges).
  bool filteredDetection = true;
  /// Sources seen only in the filtered stack (SNR >= weakSnr there, away from the per-pixel detections)
  /// are static only when their peaks in the stacks of the first and of the second half of the frames are
  /// within maxHalfShiftPx (a moving object slow enough to look like a star in the sky-rate stack is a
  /// streak whose halves shift by |v - sky rate| * span / 2). weakSnr < snrThreshold: a margin for stars that
  /// the search, maximising over velocities and positions, lifts just above its threshold.
  double weakSnr = 6.0;
  double maxHalfShiftPx = 2.5;
  /// Mask every star out to where its Moffat wing (beta wingBeta) falls below one stack sigma per pixel.
  bool maskWings = true;
  double wingBeta = 4.0;  ///< paper §3.3: beta ~ 4 (the PSF is fitted after this stage)
  /// Spikes and bleed trails are measured and masked for saturated stars and stars above this stack SNR.
  double spikeSnr = 300.0;
  /// Sources of the per-pixel detection whose centroid moves between the sky-rate stacks of the first and
  /// the last third of the frames are movers (a slow moving object is a short streak there that looks like
  /// a star; a star's centroid stays put): they are not masked, not in the catalog, and are listed in
  /// StaticSources::movers. Moving means a shift > max(minMoverShiftPx, moverShiftSigmas * its sigma) and a
  /// middle third on the line (detail::measureMotion). Saturated stars (full well reached in a frame, or
  /// at saturationLevel) are always static; bright unsaturated sources, above spikeSnr included, are judged
  /// (a bright slow asteroid, the paper's 2009 BL2, is one), and above spikeSnr must also vacate their
  /// first-third place (detail::vacates: a saturated star not recognised as such keeps its core there). The
  /// floor covers what the sigma (stack noise only) leaves out: the source's photon noise, the sky rate's
  /// integer shifts (<= 0.5 px) and guiding; a star's shift is a few tenths of a pixel.
  bool keepMovers = true;
  /// In a drifting field (the stars move >= one FWHM over the span) the stars are subtracted by
  /// subtractStarTemplate over StaticSources::subtractRegion, and `mask` covers only where single frames see
  /// them (as in a static field); off: every star is masked down to one stack sigma.
  bool subtractStars = true;
  double minMoverShiftPx = 1.0;
  double moverShiftSigmas = 5.0;
  /// Only the catalogue that a PSF fit needs (issue 16): the sources seen per pixel, movers left out, with
  /// their flux, peak and saturation; no filtered detection, no halves' test, no footprints (`mask` and
  /// `subtractRegion` stay empty, `moverMask` is not dilated). What the pipeline runs before the PSF is
  /// fitted, so that the whole search runs once, at the fitted FWHM.
  bool catalogueOnly = false;
};

/// One static source, at the reference epoch t_ref (0-based pixels; may lie outside the frame when the sky
/// drifts).
struct Star {
  double x = 0.0;            ///< flux-weighted centroid, column
  double y = 0.0;            ///< row
  double flux = 0.0;         ///< counts per frame summed over the footprint (background removed)
  double peak = 0.0;         ///< highest stacked pixel, counts per frame
  double snr = 0.0;          ///< peak SNR in the sky-rate stack
  double filteredSnr = 0.0;  ///< peak SNR in the sky-rate stack filtered by the PSF (matched filter)
  int pixels = 0;            ///< footprint size before dilation
  bool saturated = false;
  std::vector<int> bleedColumns;  ///< columns (0-based, at t_ref) with a vertical run of saturated pixels
  double motionXPx = 0.0;  ///< centroid shift between the first and last thirds' stacks (0: not measured)
  double motionYPx = 0.0;
  double motionSigmaPx = 0.0;  ///< its error (stack noise only)
};

/// A source of the sky-rate stack found to move (StaticSourceParams::keepMovers): left for the search.
struct MovingSource {
  double x = 0.0;  ///< position at t_ref from the thirds' centroids, 0-based px
  double y = 0.0;
  Velocity v;            ///< velocity in the frames (sky rate + shift between the thirds / their time), px/s
  double shiftPx = 0.0;  ///< centroid shift between the first and last thirds' stacks
  double shiftSigmaPx = 0.0;  ///< its error from the stack noise
  double snr = 0.0;           ///< peak SNR in the sky-rate stack (of its streak)
  bool moving = false;        ///< the decision of detail::measureMotion
};

struct StaticSources {
  std::vector<Star> stars;           ///< sorted by decreasing flux
  MovingMask mask;                   ///< footprints, dilated, at t_ref; follows the sky rate
  std::vector<MovingSource> movers;  ///< sources of the stack that moved: not in `stars`, not masked
  MovingMask moverMask;  ///< the movers' footprints (streaks in the sky-rate stack), dilated like `mask`
  /// Drifting field with subtractStars: the stars' wide footprints (down to one stack sigma, dilated for
  /// sub-pixel motion) where their template is subtracted; empty otherwise.
  MovingMask subtractRegion;
  double stackNoise = 0.0;  ///< single-frame noise implied by the stack: SNR = R sqrt(count) / stackNoise
  /// Wall time of the search's parts, for the notes: the stack, its analysis (mesh backgrounds, SNR
  /// maps), the components, describing them, their motions (the stacks of the thirds), the footprints.
  TimedParts parts;
};

/// Finds static sources in the stack of `cube` at `skyRate` (px/s) with `background` (a scalar, e.g. the
/// global clip mean) removed and a mesh background of the stack subtracted. Seeds are pixels with stack SNR
/// >= snrThreshold (per pixel, or after the PSF filter), grown over connected pixels down to growSnr. Each
/// star's footprint is its pixels, a disc out to where its wings fall below one stack sigma (wingRadius),
/// and for saturated/very bright stars the measured spike arms along the detector axes and the bleed
/// columns followed up and down while significant (bleed columns are at t_ref; they move with the star, so
/// in frame n they are the detector columns X + sx_n, i.e. only frames that see the star). The mask is then
/// dilated by ceil(dilateFwhm * FWHM) + 1 px. The stacks come from `stacks` when given (shared with a
/// second search of the same cube at another FWHM, and with the PSF stage). Throws st::Cancelled.
StaticSources findStaticSources(const FrameCube& cube, Velocity skyRate, double background,
                                const StaticSourceParams& params, ProgressSink& progress, CancelToken& cancel,
                                SkyStackCache* stacks = nullptr);

/// Has `stacks` make ahead, on its provider's thread, the stacks that findStaticSources with `params` asks
/// for beyond the whole cube's: the thirds' (movers) and the halves' (sources seen only after the filter,
/// which a search of many stars always has). For a caller with other work before the search (the pipeline's
/// PSF fit, issue 16); nothing without a provider (SkyStackCache::prefetch).
void prefetchStaticSourceStacks(const FrameCube& cube, Velocity skyRate, double background,
                                const StaticSourceParams& params, SkyStackCache& stacks);

/// The reference positions (x0 + i, y0 + j) that `mask`'s canvas sets, row by row (zeroMasked's list, shared
/// with the GPU path).
std::vector<std::pair<int, int>> maskedPositions(const MovingMask& mask);

/// The detector pixels (row-major, width x height) that `mask` covers in some frame: its set positions moved
/// by each distinct shift (zeroUnmeasured's keep mask, shared with the GPU path).
std::vector<std::uint8_t> coveredInSomeFrame(const MovingMask& mask, int width, int height);

/// Sets every pixel covered by `mask` to 0 in every frame (frames must be zero-biased). Returns the number of
/// pixels zeroed over all frames.
std::size_t zeroMasked(FrameCube& cube, const MovingMask& mask, ProgressSink& progress, CancelToken& cancel);

/// Zeroes, in every frame, the pixels flagged in `unmeasured` (row-major, frame-sized: pixels whose
/// per-pixel background had too few samples, so the global mean stood in) that `keep` (the movers) covers in
/// no frame. Such pixels are (1) along the static mask's edge, which the integer sky-rate shifts move by a
/// pixel or two from frame to frame: covered in most frames, they keep a bright star's halo (broader than
/// the Moffat wings masked) in the few frames that uncover them; (2) bright static light that the stack's
/// mesh background absorbed (a saturated star's halo and its islands between mask pieces), above the
/// background's strong-signal cut in most frames (while that cut was the global mean + 5 sigma; since
/// 2026-11-27 it is relative to each pixel's own median, so static light is its own background and only
/// case 1 remains). Either leaves a static residual that the search finds near the sky rate. Returns the
/// number of pixels zeroed (each counted once).
std::size_t zeroUnmeasured(FrameCube& cube, const std::vector<std::uint8_t>& unmeasured,
                           const MovingMask& keep);

struct SingleFrameSources {
  std::vector<std::size_t> seedsPerFrame;   ///< pixels at or above the threshold, per frame
  std::vector<std::size_t> zeroedPerFrame;  ///< pixels zeroed (seeds dilated), per frame
};

/// Paper §4.3: in zero-biased frames, pixels with value >= snr * sigma (sigma: per-pixel noise image, or
/// sigmaN when `sigma` is empty) are bright objects of that frame alone; they are zeroed together with a
/// disc of `radiusPx` around them, in that frame only. Pixels covered by `keep` in that frame (the movers of
/// findStaticSources, left for the search) are not seeds.
SingleFrameSources zeroSingleFrameSources(FrameCube& cube, const Image& sigma, double sigmaN, double snr,
                                          int radiusPx, ProgressSink& progress, CancelToken& cancel,
                                          const MovingMask* keep = nullptr);

}  // namespace st::detect

#pragma once
// Background and noise (paper §3.1 and §4.2): a pixel-independent background from ~50 frames (xi = 5),
// then a pixel-dependent background from up to ~2000 frames per pixel (xi = 4), the noise sigma_n from the
// frame-to-frame variation averaged over pixels, an optional smooth noise map, and the subtraction that
// makes the frames zero-biased.
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "st/common/frame_cube.hpp"
#include "st/common/image.hpp"
#include "st/common/progress.hpp"
#include "st/common/moving_mask.hpp"
#include "st/stats/sigma_clip.hpp"

namespace st::stats {

struct GlobalBackgroundParams {
  std::size_t frames = 50;  ///< frames used, evenly spaced over the cube (paper §4.2: 50)
  double xi = 5.0;          ///< clip threshold (paper §3.1: 5)
};

/// The pixel-independent background: the one-sided clip (sigmaClip) of every unmasked pixel of up to
/// `params.frames` frames. Throws st::InputError when every one of those pixels is masked.
ClipStats globalBackground(const FrameCube& cube, const GlobalBackgroundParams& params = {});

struct BackgroundParams {
  GlobalBackgroundParams global;  ///< the pixel-independent first estimate (paper: 50 frames, xi = 5)
  double xi = 4.0;                ///< per-pixel clip threshold (paper §3.1: 4)
  std::size_t maxFrames = 2000;   ///< frames per pixel, evenly spaced when the cube has more (paper: ~2000)
  /// Samples above the pixel's own median (the lower median of its samples not masked or excluded) + this
  /// x the global sigma are left out first ("eliminate most of the strong signals", paper §4.2). Relative
  /// to the pixel, not to the global mean (before 2026-11-27): a pixel bright in every frame (a static
  /// star's wing just outside its mask) lost the upper part of its own noise to a global cut, its
  /// background came out low and the static residual was found by the search at near-zero velocity. A
  /// source on the pixel in fewer than half of its samples (a mover) is still cut; one on it in more than
  /// half sets the level (a source that stays put that long is a static source for the masks to handle).
  double strongSignalXi = 5.0;
  std::size_t minSamples = 10;    ///< pixels with fewer background samples take the global mean
  bool noiseMap = false;          ///< also compute a smooth noise map (box mean of the per-pixel sigma)
  int noiseMapBoxPx = 33;         ///< side of that box, pixels
  /// subtractPixelBackground: frame n's background at a pixel leaves out the samples of the frames within
  /// +- this fraction of the time span of frame n, so that a mover crossing the pixel in that time does not
  /// subtract its own flux (movers faster than about FWHM / (fraction x span) keep all of it). 0 = the
  /// paper's one mean per pixel.
  double moverWindowFraction = 0.25;
};

struct Background {
  Image level;                   ///< per-pixel background (mean of the converged set B), counts
  Image sigma;                   ///< per-pixel frame-to-frame standard deviation of B, counts
  double sigmaN = 0.0;           ///< noise of one pixel of one frame: sqrt(mean over pixels of sigma^2)
  ClipStats global;              ///< the pixel-independent estimate it started from
  std::size_t framesUsed = 0;    ///< frames that entered the per-pixel clip
  std::size_t pixelsFilled = 0;  ///< pixels with < minSamples samples (level = global mean, not in sigmaN)
  std::vector<std::uint8_t> filled;  ///< 1 for those pixels (row-major, width x height)
  Image noiseMap;                    ///< smooth noise map when params.noiseMap, else empty
};

/// Per-pixel background of the cube (paper §3.1 with xi = 4 over up to ~2000 frames). Masked samples, samples
/// covered by `exclude` (static sources following the sky motion; may be null) and strong signals are left
/// out. Tiled by rows over worker threads; the clip of each pixel gives exactly sigmaClip's result on that
/// pixel's samples. Throws st::InputError when no pixel has enough samples; st::Cancelled.
Background estimateBackground(const FrameCube& cube, const BackgroundParams& params,
                              const MovingMask* exclude, ProgressSink& progress, CancelToken& cancel);

/// estimateBackground, then the subtraction in place of a background per frame and pixel: the mean of the
/// pixel's clipped background samples outside +- moverWindowFraction x span of the frame (the whole clipped
/// mean when fewer than min(minSamples, max(4, a third of the clipped samples)) remain, or when the frame
/// times are not sorted). Masked pixels become 0.
/// Returns what estimateBackground returns (`level` is the whole clipped mean, for display).
Background subtractPixelBackground(FrameCube& cube, const BackgroundParams& params,
                                   const MovingMask* exclude, ProgressSink& progress,
                                   CancelToken& cancel);

/// What subtractPixelBackground takes into frame n's background, for a model of the flux a mover gives its
/// own background (fit::FitOptions::selfSubtraction): the mean over the `frames` (the evenly spaced set the
/// per-pixel clip uses) that lie outside +- windowS of frame n; the mean over all of them when fewer than
/// minOutside remain (the per-pixel rule with every sample clipped in) or when windowS is 0. Samples more
/// than clipXi sigma above the pixel's level are clipped out of the mean.
struct PixelBackgroundWindows {
  std::vector<std::size_t> frames;
  double windowS = 0.0;
  std::size_t minOutside = 0;
  double clipXi = 4.0;
  [[nodiscard]] bool empty() const noexcept { return frames.empty(); }
  /// The windows of a cube of `frameCount` frames whose per-pixel clip used `setSize` evenly spaced frames
  /// (BackgroundParams::maxFrames; all when at least frameCount); what pixelBackgroundWindows builds, and
  /// what a prepared cube's header records (pipeline::preparedBackgroundWindows).
  [[nodiscard]] static PixelBackgroundWindows evenlyOver(std::size_t frameCount, std::size_t setSize,
                                                         double windowS, std::size_t minOutside,
                                                         double clipXi);
  /// The [lo, hi) range of `frames` (indices into it) within +- windowS of frame n (lo == hi when windowS is
  /// 0): what subtractPixelBackground leaves out of a pixel's samples before its per-pixel count rule.
  /// `timesS` are the cube's time offsets.
  [[nodiscard]] std::pair<std::size_t, std::size_t> window(std::size_t n,
                                                           const std::vector<double>& timesS) const;
  /// window(), or an empty range when fewer than minOutside frames would remain (the whole mean is taken).
  [[nodiscard]] std::pair<std::size_t, std::size_t> leftOut(std::size_t n,
                                                            const std::vector<double>& timesS) const;
};
[[nodiscard]] PixelBackgroundWindows pixelBackgroundWindows(const FrameCube& cube,
                                                            const BackgroundParams& params);

/// Subtracts `level` from every frame in place; masked pixels become 0, so the frames are zero-biased and
/// carry no NaN. Throws st::InputError when the sizes differ.
void subtractBackground(FrameCube& cube, const Image& level, ProgressSink& progress, CancelToken& cancel);

/// Box mean (side `box`, odd) of `image` over pixels where `valid` is non-zero (all when empty).
Image boxSmooth(const Image& image, int box, const std::vector<std::uint8_t>& valid = {});

}  // namespace st::stats

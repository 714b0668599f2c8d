#pragma once
// Private helpers of findStaticSources: the matched-filtered SNR of the sky-rate stack (what the velocity
// search sees at the sky rate) and the extra footprint of bright and saturated stars (Moffat wings,
// diffraction spikes along the detector axes, column bleed trails), all in canvas coordinates of the sky-rate
// stack.
#include <vector>

#include "st/common/frame_cube.hpp"
#include "st/common/image.hpp"
#include "st/common/progress.hpp"
#include "st/detect/moving_mask.hpp"
#include "st/detect/sky_stack.hpp"
#include "st/detect/static_sources.hpp"

namespace st::detect::detail {

/// SNR of the stack filtered by a Moffat kernel (FWHM fwhmPx, beta 4): sum K r c / (sigma sqrt(sum K^2 c)),
/// with r the background-subtracted stack mean, c the count of contributing frames and sigma the single-frame
/// noise. This is the matched-filter SNR of a point source seen in c frames (partial N_in at the edges).
/// `device`, when given, makes it from FilteredSnrInputs (the same values) unless it declines.
std::vector<float> filteredSnr(const Image& resid, const Image& count, double sigma, double fwhmPx,
                               const SkyStackCache::SnrProvider* device = nullptr);

/// Filtered SNR maps of the sky-rate stacks of the first and second halves of the frames (same canvas).
struct HalfStacks {
  std::vector<float> first, second;
  Image countFirst, countSecond;
  [[nodiscard]] bool empty() const noexcept { return first.empty(); }
  /// Whether the source whose full-stack filtered peak is canvas pixel `peak` (canvas width cw) is static:
  /// where both halves see it in at least a fifth of its frames, (1) its filtered SNRs in the halves agree
  /// with one flux (|Fa sqrt(cb) - Fb sqrt(ca)| / sqrt(ca + cb) <= 3: a piece of a streak is in one half
  /// only) and (2) the halves' peaks within radiusPx of `peak` are within maxShiftPx (the centre of a
  /// streak: each half peaks on its own half of the streak), widened by 1.5 FWHM / (weaker half's SNR) for
  /// the peak-location noise; radiusPx = ceil(FWHM) + 1. Sources that one half barely sees (stars at the
  /// edges) are static.
  [[nodiscard]] bool isStatic(int peak, int cw, double fwhmPx, double maxShiftPx) const;
};
HalfStacks halfStacks(const FrameCube& cube, Velocity skyRate, double background, const Image& local,
                      double sigma, double fwhmPx, SkyStackCache& stacks, CancelToken& cancel);
/// The frame ranges halfStacks stacks for a cube of `frames` frames.
std::vector<SkyStackCache::Range> halfRanges(std::size_t frames);

/// `count` with 0 wherever snr or snrF is at least `level`, dilated by a square of +-growPx: the weight of
/// a background that leaves the sources out.
Image excludeSources(const Image& count, const std::vector<float>& snr, const std::vector<float>& snrF,
                     double level, int growPx);

/// Radius (px) beyond which a Moffat star (FWHM fwhmPx, beta) of `flux` counts per frame stacked over
/// `frames` frames is fainter than one stack sigma per pixel (sigma / sqrt(frames)).
double wingRadiusPx(double flux, double fwhmPx, double beta, double frames, double sigma);

/// Measures the four diffraction-spike arms of `star` along +-x and +-y (canvas coordinates via x0/y0) in the
/// stack and sets them in `mask` with a half-width of halfWidthPx. Returns the longest arm (px).
int maskSpikes(MovingMask& mask, const Image& resid, const Image& count, double sigma, int x0, int y0,
               const Star& star, int coreRadiusPx, int halfWidthPx);

/// Follows each of the star's bleed columns up and down in the stack while it stays significant and sets
/// those columns (+- halfWidthPx) in `mask`. Returns the number of rows set in the longest trail.
int maskBleed(MovingMask& mask, const Image& resid, const Image& count, double sigma, int x0, int y0,
              const Star& star, int halfWidthPx);

/// Sets a disc of radius r around (x, y) (reference positions) in `mask`; nothing when r <= 0.
void setDisc(MovingMask& mask, double x, double y, double r);

}  // namespace st::detect::detail

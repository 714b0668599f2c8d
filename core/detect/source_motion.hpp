#pragma once
// Private helper of findStaticSources: does a source of the sky-rate stack move? Its centroid is measured,
// over the same footprint, in the sky-rate stacks of the first, middle and last thirds of the frames. A star
// stays put (seeing changes convolve it with a centred PSF, which keeps its centroid), a slow moving object
// is a streak in the full stack whose thirds sit at its two ends and its middle.
#include <array>
#include <vector>

#include "st/common/frame_cube.hpp"
#include "st/common/image.hpp"
#include "st/common/progress.hpp"
#include "st/common/units.hpp"
#include "st/detect/sky_stack.hpp"
#include "st/detect/static_sources.hpp"

namespace st::detect::detail {

/// The sky-rate stacks of the three thirds of the frames (by index; frames in time order) on the canvas of
/// the full stack, each less its own mesh background (cells of meshPx: the sky level drifts during a night,
/// and an offset left in a third pulls its centroids towards the footprint's centre), with their
/// contributing-frame counts, the number of frames and the mean time offset t - t_ref (s) of each third,
/// and the mean sub-pixel residual v (t_n - t_ref) - round(v (t_n - t_ref)) of the integer shifts (a static
/// source sits that far from its t_ref position in that third's stack: up to 0.5 px). Empty (valid() false)
/// below 6 frames.
struct ThirdStacks {
  std::array<Image, 3> resid;
  std::array<Image, 3> count;
  std::array<int, 3> frames{};
  std::array<double, 3> meanTimeS{};
  std::array<double, 3> residualX{}, residualY{};
  [[nodiscard]] bool valid() const noexcept { return !resid[0].pixels.empty(); }
};
ThirdStacks thirdStacks(const FrameCube& cube, Velocity skyRate, double background, int meshPx,
                        SkyStackCache& stacks, CancelToken& cancel);
/// The frame ranges thirdStacks stacks for a cube of `frames` frames (none below 6 frames).
std::vector<SkyStackCache::Range> thirdRanges(std::size_t frames);

/// A source's centroids (canvas px, less the integer-shift residuals) in the three thirds, with their
/// variances from the stack noise (single-frame sigma / sqrt(count) per pixel; the source's own photon
/// noise is not included). measured: every footprint pixel is seen by every frame of each third (sources
/// at the edges, partly seen, are not judged) and each third sees the source with flux SNR >= 5.
struct SourceShift {
  bool measured = false;
  std::array<double, 3> x{}, y{}, varX{}, varY{};
};

/// Flux-weighted centroids over the footprint `comp` (canvas pixel indices, canvas width cw) with signed
/// weights (unbiased for any source once the background is removed).
SourceShift measureShift(const std::vector<int>& comp, int cw, const ThirdStacks& thirds, double sigma);

/// The stars' common shift between the first and last thirds (px): the median over the measured sources
/// of each component (an error of the sky rate, or a drift of the guiding, moves every star alike), or 0
/// with fewer than 3 measured sources.
std::pair<double, double> commonShift(const std::vector<SourceShift>& shifts);

/// The decision on one measured source, its shift taken relative to `common`: moving when (1) the shift d
/// between the first and last thirds exceeds max(params.minMoverShiftPx, params.moverShiftSigmas *
/// sigma_d) and (2) the middle third's centroid lies where linear motion puts it, within 0.25 |d| +
/// params.moverShiftSigmas * its sigma (a cosmic ray or a defect in one third moves one centroid only).
/// Position at t_ref and velocity (relative to the sky rate, px/s) from the outer thirds; x0/y0: canvas
/// origin. Fills star.motionXPx / motionYPx / motionSigmaPx.
MovingSource judgeMotion(const SourceShift& shift, std::pair<double, double> common,
                         const ThirdStacks& thirds, int x0, int y0, const StaticSourceParams& params,
                         Star& star);

/// For a bright source (above StaticSourceParams::spikeSnr) found moving: does it leave where it was? The
/// brightest footprint pixel of the first third's stack and that of the last third's are >= 2 FWHM apart,
/// and the flux in a disc of radius FWHM around each is < half as large in the other outer third. A moving
/// object vacates its earlier place; a saturated star whose bleed trail or flat-fielded plateau changes
/// between thirds (its centroid shifts by pixels: real frames without SATURATE, where the flat spreads the
/// full-well pixels by more than the flat-top test's 3%) keeps its core in both.
bool vacates(const std::vector<int>& comp, int cw, const ThirdStacks& thirds, double fwhmPx);

}  // namespace st::detect::detail

#pragma once
// Construction of the trial-velocity grid (paper §4.4) and the cost estimate shown before a search starts.
// Pure arithmetic, tested exactly.
//
// Range: a half-width around the centre, in px/s, arcsec/min or deg/day (the last two need the plate
// scale). Centre: by default the sky rate measured in pre-processing (FilteredCube::skyRate; the paper's
// telescope scanned, so its +-12 deg/day grid was relative to the stars), or any given velocity.
// Spacing: paper §4.4, "the grid spacing should be no more than the size of the PSF divided by the
// integration time"; the paper used 1 px / integration time. Default here: 1 px over the time span of the
// cube (last minus first frame mid-time), i.e. a velocity error of half a step moves the source by at most
// 1/4 px at the ends of the cube; StepRule::FwhmOverSpan gives the coarser PSF-FWHM / span, and an explicit
// step in px (of motion over the span) or in px/s can be given.
// Count per axis: 2 * ceil(halfRange / step) + 1 points, odd, so the centre is a grid point and the grid
// covers at least +-halfRange.
#include <cstddef>
#include <cstdint>
#include <optional>

#include "st/common/units.hpp"
#include "st/search/types.hpp"

namespace st::search {

enum class VelocityUnit { PxPerS, ArcsecPerMin, DegPerDay };

enum class StepRule {
  PixelsOverSpan,  ///< step = stepPx / timeSpan (default stepPx = 1, the paper's 1 px / integration time)
  FwhmOverSpan,    ///< step = PSF FWHM / timeSpan (the paper's upper limit)
  PxPerS,          ///< step = stepPxS as given
};

struct GridSpec {
  double halfRange = 0.0;                        ///< half-width of the grid in `unit` (both axes)
  VelocityUnit unit = VelocityUnit::PxPerS;      ///< unit of halfRange
  std::optional<double> plateScaleArcsecPerPx;   ///< needed for arcsec/min and deg/day
  std::optional<Velocity> centre;                ///< px/s; default: the cube's sky rate
  StepRule stepRule = StepRule::PixelsOverSpan;  ///< spacing rule
  double stepPx = 1.0;                           ///< motion over the span per step (PixelsOverSpan)
  double stepPxS = 0.0;                          ///< explicit step, px/s (StepRule::PxPerS)
  std::size_t maxVelocities = 25'000'000;        ///< refuse larger grids (time and map memory)
};

/// Converts a speed in `unit` to px/s. Throws st::InputError when a plate scale is needed and missing or
/// not positive.
double toPxPerS(double value, VelocityUnit unit, std::optional<double> plateScaleArcsecPerPx);

/// The grid step in px/s for `spec` (see StepRule). timeSpanS: last minus first frame mid-time; fwhmPx: PSF
/// FWHM. Throws st::InputError for a zero or negative span (one frame), step or FWHM.
double gridStepPxS(const GridSpec& spec, double timeSpanS, double fwhmPx);

/// Builds the grid. skyRate is the default centre. Throws st::InputError naming the value for a negative
/// or non-finite range, a zero step, a zero time span, or a grid of more than spec.maxVelocities points
/// (the message says how many were asked for and which step would fit).
VelocityGrid makeVelocityGrid(const GridSpec& spec, double timeSpanS, double fwhmPx, Velocity skyRate);

/// Convenience: the grid for a filtered cube (its time span, PSF FWHM and sky rate).
VelocityGrid makeVelocityGrid(const GridSpec& spec, const FilteredCube& cube);

/// The trial counts of a full-frame search (N_x = width, N_y = height, N_vx, N_vy).
TrialCounts trialCounts(int width, int height, const VelocityGrid& grid);

/// What a search will cost, shown before it starts.
struct SearchEstimate {
  double additions = 0.0;        ///< pixel x frame x velocity additions of the exact search
  std::size_t cubeBytes = 0;     ///< the cube, already held (float32)
  std::size_t workingBytes = 0;  ///< what the search allocates on top of the cube (scratch, map, results)
  double seconds = 0.0;          ///< additions / throughput
  double throughputPerS = 0.0;   ///< additions per second used for `seconds`
};

/// Additions per second of the CPU exact backend per worker thread, calibrated with
/// `synthtrack-cli bench search` on the 2-core development machine (AMD EPYC Zen 3, AVX2): 1.3e10 additions
/// per CPU-second, 2026-11-22; rounded down for the second thread sharing L3 and memory.
inline constexpr double kCpuAdditionsPerSecondPerThread = 1.2e10;

/// Estimates time and memory of an exact search of `frames` frames of width x height over `grid`, with
/// `threads` workers at `additionsPerSecond` in all (default: kCpuAdditionsPerSecondPerThread * threads).
SearchEstimate estimateSearch(int width, int height, std::size_t frames, const VelocityGrid& grid,
                              unsigned threads, std::optional<double> additionsPerSecond = std::nullopt);

}  // namespace st::search

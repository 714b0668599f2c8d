#include "st/search/velocity_grid.hpp"

#include <cmath>
#include <sstream>

#include "ipsa_kernel.hpp"
#include "st/common/error.hpp"

namespace st::search {

namespace {

std::string unitName(VelocityUnit unit) {
  switch (unit) {
    case VelocityUnit::PxPerS:
      return "px/s";
    case VelocityUnit::ArcsecPerMin:
      return "arcsec/min";
    case VelocityUnit::DegPerDay:
      return "deg/day";
  }
  return "?";
}

}  // namespace

double toPxPerS(double value, VelocityUnit unit, std::optional<double> plateScale) {
  if (unit == VelocityUnit::PxPerS) return value;
  if (!plateScale || !(*plateScale > 0.0) || !std::isfinite(*plateScale)) {
    std::ostringstream os;
    os << "a velocity in " << unitName(unit) << " needs a positive plate scale (arcsec/px)";
    if (plateScale)
      os << ", got " << *plateScale;
    else
      os << "; the data has no WCS and none was given";
    throw InputError(os.str());
  }
  return unit == VelocityUnit::ArcsecPerMin ? arcsecPerMinToPxPerSec(value, *plateScale)
                                            : degPerDayToPxPerSec(value, *plateScale);
}

double gridStepPxS(const GridSpec& spec, double timeSpanS, double fwhmPx) {
  if (spec.stepRule == StepRule::PxPerS) {
    if (!(spec.stepPxS > 0.0) || !std::isfinite(spec.stepPxS)) {
      throw InputError("velocity grid step must be positive, got " + std::to_string(spec.stepPxS) + " px/s");
    }
    return spec.stepPxS;
  }
  if (!(timeSpanS > 0.0) || !std::isfinite(timeSpanS)) {
    throw InputError("the cube spans no time (time span " + std::to_string(timeSpanS) +
                     " s): a velocity search needs at least two frames at different times");
  }
  if (spec.stepRule == StepRule::FwhmOverSpan) {
    if (!(fwhmPx > 0.0) || !std::isfinite(fwhmPx)) {
      throw InputError("grid step from the PSF needs a positive FWHM, got " + std::to_string(fwhmPx) + " px");
    }
    return fwhmPx / timeSpanS;
  }
  if (!(spec.stepPx > 0.0) || !std::isfinite(spec.stepPx)) {
    throw InputError("velocity grid step must be positive, got " + std::to_string(spec.stepPx) +
                     " px of motion over the time span");
  }
  return spec.stepPx / timeSpanS;
}

VelocityGrid makeVelocityGrid(const GridSpec& spec, double timeSpanS, double fwhmPx, Velocity skyRate) {
  const double half = toPxPerS(spec.halfRange, spec.unit, spec.plateScaleArcsecPerPx);
  if (!(half >= 0.0) || !std::isfinite(half)) {
    throw InputError("velocity range must be a finite half-width >= 0, got " +
                     std::to_string(spec.halfRange) + " " + unitName(spec.unit));
  }
  VelocityGrid grid;
  grid.centre = spec.centre.value_or(skyRate);
  if (!std::isfinite(grid.centre.vx) || !std::isfinite(grid.centre.vy)) {
    throw InputError("velocity grid centre is not finite");
  }
  grid.stepPxS = gridStepPxS(spec, timeSpanS, fwhmPx);
  // The small tolerance keeps an exact multiple (range 10, step 1) at 21 points despite rounding.
  const double halfSteps = std::ceil(half / grid.stepPxS - 1e-9);
  const double perAxis = 2.0 * halfSteps + 1.0;
  const double total = perAxis * perAxis;
  if (total > static_cast<double>(spec.maxVelocities)) {
    const double fitPerAxis = std::floor(std::sqrt(static_cast<double>(spec.maxVelocities)));
    const double fitStep = 2.0 * half / std::max(1.0, fitPerAxis - 1.0);
    std::ostringstream os;
    os << "velocity grid of " << perAxis << " x " << perAxis << " = " << total << " velocities (half-range "
       << half << " px/s, step " << grid.stepPxS << " px/s) exceeds the limit of " << spec.maxVelocities
       << " velocities; at most " << fitPerAxis << " per axis fit: use a step of at least " << fitStep
       << " px/s (" << fitStep * (timeSpanS > 0 ? timeSpanS : 1.0)
       << " px over the time span) or a smaller range";
    throw InputError(os.str());
  }
  grid.nvx = static_cast<int>(perAxis);
  grid.nvy = static_cast<int>(perAxis);
  return grid;
}

VelocityGrid makeVelocityGrid(const GridSpec& spec, const FilteredCube& cube) {
  GridSpec s = spec;
  if (!s.plateScaleArcsecPerPx) s.plateScaleArcsecPerPx = cube.frames.plateScaleArcsecPerPx;
  return makeVelocityGrid(s, cube.frames.timeSpanS(), cube.psfFwhmPx, cube.skyRate);
}

TrialCounts trialCounts(int width, int height, const VelocityGrid& grid) {
  return TrialCounts{width, height, grid.nvx, grid.nvy};
}

SearchEstimate estimateSearch(int width, int height, std::size_t frames, const VelocityGrid& grid,
                              unsigned threads, std::optional<double> additionsPerSecond) {
  SearchEstimate e;
  const double pixels = static_cast<double>(width) * static_cast<double>(height);
  e.additions = pixels * static_cast<double>(frames) * static_cast<double>(grid.count());
  e.cubeBytes = static_cast<std::size_t>(pixels) * frames * sizeof(float);
  e.workingBytes = detail::workingBytes(width, height, frames, grid, threads);
  e.throughputPerS = additionsPerSecond.value_or(kCpuAdditionsPerSecondPerThread * std::max(1u, threads));
  e.seconds = e.throughputPerS > 0.0 ? e.additions / e.throughputPerS : 0.0;
  return e;
}

}  // namespace st::search

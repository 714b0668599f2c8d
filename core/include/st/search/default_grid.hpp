#pragma once
// The default trial-velocity grid for an opened observation, derived from the data (issue 15 item 4): the
// paper's rule for the step (1 px of motion over the time span, §4.4), and a half-range that is the
// smallest of
//   - the paper's +-12 deg/day (needs the plate scale; without one, +-12 steps as `synthtrack-cli search`),
//   - what can stay in the frame: an object faster than max(width, height) / (minFrameFraction x span) is in
//     fewer than minFrameFraction of the frames wherever it is, and the search ignores such tracks
//     (SearchParams::minFrameFraction),
//   - what the backend searches in about `budgetS` seconds with the exact method (MethodCostModel, the
//     same pricing as the estimate shown before a search; "auto" may choose the tree and be faster).
// Pure arithmetic, tested exactly (tests/core/test_default_grid.cpp). A 72-minute sidereal sequence of
// 1365 x 1370 px at 0.98"/px gets +-0.6 deg/day on 2 CPU cores instead of the paper's 19.5 M velocities.
#include <optional>
#include <string>

#include "st/search/method_choice.hpp"
#include "st/search/types.hpp"

namespace st::search {

/// Seconds of search the default grid aims at ("about a minute").
inline constexpr double kDefaultGridBudgetS = 60.0;

struct DefaultGridInput {
  int width = 0;   ///< frame size the search runs on, px
  int height = 0;
  std::size_t frames = 0;
  double timeSpanS = 0.0;                       ///< last minus first frame mid-time
  std::optional<double> plateScaleArcsecPerPx;  ///< for the paper's +-12 deg/day
  Velocity centre;                              ///< px/s: the sky rate (0 before pre-processing)
  MethodCostModel model;                        ///< the chosen backend's (cpuCostModel, cudaCostModel)
  double budgetS = kDefaultGridBudgetS;
  double minFrameFraction = 0.5;  ///< SearchParams::minFrameFraction
  double paperHalfRangeDegPerDay = 12.0;
  double stepPx = 1.0;  ///< motion over the span per step (the paper's 1 px)
};

/// Which bound set the half-range.
enum class DefaultGridLimit { Paper, Frame, Budget };

struct DefaultGrid {
  VelocityGrid grid;              ///< square, centred on DefaultGridInput::centre
  int halfSteps = 0;              ///< (nvx - 1) / 2, >= 1
  double stepPx = 1.0;            ///< the step as motion over the span, px
  double halfRangePxS = 0.0;      ///< halfSteps x step
  double paperLimitPxS = 0.0;     ///< +-12 deg/day in px/s (12 steps without a plate scale)
  double frameLimitPxS = 0.0;     ///< what can stay in the frame
  double budgetLimitPxS = 0.0;    ///< the largest half-range within budgetS (exact method)
  DefaultGridLimit limit = DefaultGridLimit::Paper;
  double exactSeconds = 0.0;      ///< estimated exact-search time of `grid` with the model
};

/// The default grid for `in` (see the top of this file). Throws st::InputError naming the value for a
/// non-positive size, frame count, time span, step or budget, or a cost model without a throughput.
DefaultGrid defaultVelocityGrid(const DefaultGridInput& in);

/// One line for people: "±0.61 deg/day in 1 px steps (227 × 227 velocities, about 58 s exact on this
/// backend): limited by the ~1 min budget (the frame allows ±15.9 deg/day, the paper ±12)". Angular units
/// when `plateScaleArcsecPerPx` is known, px/s otherwise.
std::string describeDefaultGrid(const DefaultGrid& g, std::optional<double> plateScaleArcsecPerPx);

}  // namespace st::search

#pragma once
// The demo observation's search settings, the one source for the GUI's --demo (and its Demo action) and
// `synthtrack-cli demo`: both build their grid and thresholds from here, so the two report the same
// candidates (and the same count of merged sidelobes) on the same demo observation.
#include <optional>

#include "st/search/types.hpp"
#include "st/search/velocity_grid.hpp"

namespace st::pipeline {

/// The demo's grid: +-search::kDemoHalfRangeDegPerDay (8) deg/day around the sky rate, in steps of
/// search::kDemoGridStepPx (1.5) px of motion over the time span (st/search/demo_grid.hpp). A demo setting,
/// coarser than the paper's +-12 deg/day at 1 px (§4.4) that `synthtrack-cli search` and the GUI use for
/// other observations. `plateScaleArcsecPerPx` converts deg/day to px/s (makeVelocityGrid throws st::InputError
/// without one).
[[nodiscard]] search::GridSpec demoGridSpec(std::optional<double> plateScaleArcsecPerPx);

/// The demo's thresholds and method: SNR 7 (search::SearchParams's default, paper §4.4), no FAP target,
/// method "auto" (exact or tree, whichever is estimated to win, st/search/method_choice.hpp).
[[nodiscard]] search::SearchParams demoSearchParams();

}  // namespace st::pipeline

#pragma once
// The velocity grid in use, in words and units, for the search panel: how many velocities, the range it
// covers around its centre and its step, in the shown unit and in px of motion over the observation's time
// span (the paper's §4.4 rule: 1 px), and where the setting came from (the demo's coarser setting, the
// paper's default, a restored session, or edited by hand).
#include <QString>
#include <optional>

#include "st/search/types.hpp"
#include "velocity_units.hpp"

namespace st::ui {

/// E.g. "45 × 45 = 2025 velocities\n±8.08 deg/day (±1.10 px/s) in steps of 0.367 deg/day = 1.50 px over
/// the 29.9 s span". The range is the grid's own half-width ((n - 1) / 2 steps, which covers at least the
/// range asked for). `timeSpanS` <= 0 leaves out the px-over-span part; angular units need `arcsecPerPx`
/// (px/s is shown otherwise).
[[nodiscard]] QString gridDescription(const search::VelocityGrid& grid, VelocityUnit unit,
                                      std::optional<double> arcsecPerPx, double timeSpanS);

}  // namespace st::ui

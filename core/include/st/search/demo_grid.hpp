#pragma once
// The demo's search grid, shared by the GUI's --demo, `synthtrack-cli demo` (st/pipeline/demo_search.hpp)
// and the simulator's presets (st/sim/simulator.hpp): +-8 deg/day around the sky rate in steps of 1.5 px
// over the time span. A demo setting, coarser than the paper's +-12 deg/day at 1 px (the demo object moves at
// 5.97 deg/day, and 1.5 px is half the ~3 px PSF, paper §4), so the demo's search takes seconds on a
// laptop's CPU. Here, in the search layer, so that the pipeline and the GUI need not include the simulator.

namespace st::search {

inline constexpr double kDemoHalfRangeDegPerDay = 8.0;
inline constexpr double kDemoGridStepPx = 1.5;

}  // namespace st::search

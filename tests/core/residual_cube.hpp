#pragma once
// The star-residual cube of test_pipeline_residuals, shared with test_registration: paper-neo at 256^2 x 250
// frames (EMCCD, stars drifting 16.4 px/s along +x, so the field is replaced once over the cube), 25 faint
// stars and one saturated 10.5 mag star (spikes, a bleed column) at (kSaturatedStarX, kSaturatedStarY) at
// t_ref; the object is at (128, 112).
#include "st/sim/simulator.hpp"

namespace st::test {

constexpr double kSaturatedStarX = 145.0, kSaturatedStarY = 165.0;

inline sim::SimParams residualCubeParams() {
  sim::SimParams sp = sim::preset("paper-neo");
  sim::resize(sp, 256, 256, 250);
  sp.brightStars = 0;
  sp.starCount = 25;
  sp.fixedStars = {{kSaturatedStarX, kSaturatedStarY, 10.5}};
  return sp;
}

}  // namespace st::test

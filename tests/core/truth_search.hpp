#pragma once
// Pipeline tests: search a prepared cube on the CPU and check that its best candidate is a simulated
// object (position, velocity within 1.5 grid steps, SNR >= 75% of the expected one: grid and filter losses).
#include <gtest/gtest.h>

#include <optional>

#include "st/search/cpu_backend.hpp"
#include "st/sim/truth.hpp"

namespace st::test {

/// Searches `cube` over `grid` (default parameters) and checks its best candidate against `object`: x and y
/// within `positionTolPx`, each velocity component within 1.5 grid steps, SNR >= 0.75 x expected. Returns
/// the best candidate, or nothing (a failure is recorded) when there is none.
inline std::optional<search::Candidate> expectBestIsObject(const search::FilteredCube& cube,
                                                           const search::VelocityGrid& grid,
                                                           const sim::TruthObject& object,
                                                           double positionTolPx) {
  NullProgress progress;
  CancelToken cancel;
  const search::SearchResult r = search::makeCpuBackend()->search(cube, grid, {}, progress, cancel);
  if (r.candidates.empty()) {
    ADD_FAILURE() << "no candidate";
    return std::nullopt;
  }
  const search::Candidate& best = r.candidates.front();
  EXPECT_NEAR(best.x, object.xRefPx, positionTolPx);
  EXPECT_NEAR(best.y, object.yRefPx, positionTolPx);
  EXPECT_NEAR(best.v.vx, object.vxPxPerS, 1.5 * grid.stepPxS);
  EXPECT_NEAR(best.v.vy, object.vyPxPerS, 1.5 * grid.stepPxS);
  EXPECT_GE(best.snr, 0.75 * object.expectedSnr) << "expected SNR " << object.expectedSnr;
  return best;
}

}  // namespace st::test

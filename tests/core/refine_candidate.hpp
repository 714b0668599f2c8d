#pragma once
// A candidate's SNR at the best velocity of a finer grid around it, for tests that compare two runs of the
// same object. The SNR a search reports depends on where its grid's cells fall relative to the object's true
// velocity (a bright, sharp object loses several % at half a step), and two runs whose sky rates, the grids'
// centres, differ (a dithered run's registration sets an insignificant drift to exactly 0) sample it at
// different phases; at the refined velocity the comparison is of the data, not of the grids.
#include <cmath>

#include "st/common/progress.hpp"
#include "st/search/cpu_backend.hpp"

namespace st::test {

/// Searches `cube` on a grid of quarter steps over +-1 step around c.v and returns the best candidate within
/// radiusPx of (c.x, c.y); `c` itself when none is there.
inline search::Candidate refineCandidate(const search::FilteredCube& cube, const search::Candidate& c,
                                         double stepPxS, double radiusPx = 2.0) {
  NullProgress p;
  CancelToken cancel;
  const search::VelocityGrid fine{c.v, 0.25 * stepPxS, 9, 9};
  const search::SearchResult r = search::makeCpuBackend()->search(cube, fine, {}, p, cancel);
  search::Candidate best = c;
  for (const search::Candidate& k : r.candidates)
    if (std::hypot(k.x - c.x, k.y - c.y) <= radiusPx && k.snr > best.snr) best = k;
  return best;
}

}  // namespace st::test

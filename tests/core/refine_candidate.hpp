#pragma once
// A candidate's SNR at the best velocity of a finer grid around it, for tests that compare two runs of the
// same object. The SNR a search reports depends on where its grid's cells fall relative to the object's true
// velocity (a bright, sharp object loses several % at half a step), and two runs whose sky rates, the grids'
// centres, differ (a dithered run's registration sets an insignificant drift to exactly 0) sample it at
// different phases; at the refined velocity the comparison is of the data, not of the grids.
#include <cmath>
#include <cstdint>
#include <utility>

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

/// refineCandidate at the best phase of the pixel lattice. The search's shifts are round(o_n + v (t_n - t_ref)):
/// where the rounding falls relative to an object's sub-pixel track is a lottery that two runs of the same
/// data draw differently whenever their offsets o_n differ by a constant (a dithered run's offsets are
/// measured from its first frame, the undithered run's linear model from t_ref). For a bright undersampled
/// object it is worth several %: 5945 on the Lowell frames (FWHM 1.6 px, 15 frames, ~9 px of motion) gave
/// SNR 1187 with the lattice as it was and 1115 with every o_n moved by 0.31 px (2026-11-27). So the
/// comparison is made at each run's best of phases x 4 x phases per axis: a constant c added to every o_n,
/// c in {0, 1/phases, ...}, the object's position expressed in the original lattice again (within 1 px).
/// `cube` is restored before returning.
inline search::Candidate refineCandidatePhase(search::FilteredCube& cube, const search::Candidate& c,
                                              double stepPxS, int phases = 4) {
  const std::uint64_t revision = cube.revision;
  auto& info = cube.frames.info();
  search::Candidate best = c;
  for (int i = 0; i < phases; ++i) {
    for (int j = 0; j < phases; ++j) {
      const double cx = static_cast<double>(i) / phases, cy = static_cast<double>(j) / phases;
      for (auto& f : info) {
        f.offsetXPx += cx;
        f.offsetYPx += cy;
      }
      cube.revision = 0;
      const search::Candidate k = refineCandidate(cube, c, stepPxS);
      for (auto& f : info) {
        f.offsetXPx -= cx;
        f.offsetYPx -= cy;
      }
      if (k.snr > best.snr) best = k;
    }
  }
  cube.revision = revision;
  return best;
}

}  // namespace st::test

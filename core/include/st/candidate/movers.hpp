#pragma once
// Pre-processing's moving sources (detect::MovingSource: sources of the sky-rate stack whose centroid moved
// between the stacks of the first and last thirds of the frames) as candidates, so that an astronomer can
// vet them beside the search's (issue 18 §6). A mover the search found already is not listed twice.
#include <string>
#include <vector>

#include "st/detect/static_sources.hpp"
#include "st/search/types.hpp"

namespace st::candidate {

/// A candidate made from a mover has clusterCells = 0 (no search cell: the search's clusters have >= 1).
inline constexpr int kMoverClusterCells = 0;
[[nodiscard]] inline bool isMover(const search::Candidate& c) noexcept {
  return c.clusterCells == kMoverClusterCells;
}

/// The movers (`moving` true) of `movers` that no candidate of `existing` already is (within `matchPx` px in
/// position at t_ref and `matchVPxS` px/s in velocity), as candidates: position rounded to the pixel,
/// velocity as pre-processing measured it (px/s, in the frames), SNR the streak's peak SNR in the sky-rate
/// stack (not the search statistic), nIn = `frames`, fap = 1 (not a search trial), clusterCells =
/// kMoverClusterCells. In the movers' order.
[[nodiscard]] std::vector<search::Candidate> moverCandidates(const std::vector<detect::MovingSource>& movers,
                                                             const std::vector<search::Candidate>& existing,
                                                             int frames, double matchPx = 3.0,
                                                             double matchVPxS = 1.0);

/// A note for a mover's vetting state: "pre-processing mover: shift 4.2 px (9.1 sigma) between the first and
/// last thirds, SNR 12.3 in the sky-rate stack".
[[nodiscard]] std::string moverNote(const detect::MovingSource& mover);

}  // namespace st::candidate

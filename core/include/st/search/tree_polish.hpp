#pragma once
// Exact re-scoring of a tree search's candidates. The tree's sums are approximate (issue 16: up to ~1% of
// the SNR at the paper's PSF), and they can move the best cell: on paper-neo seeds 41-130 (H200, CPU,
// 2026-12-04) the tree put the asteroid's cell 2 grid steps off the truth on 2 seeds (72: vx 15.79 against
// 15.687 px/s, where the exact search picks 15.74) and 1.9 steps on a third. Each candidate is searched again
// on the exact statistic over +-1 px and +-2 grid steps around its cell (cells of the search's grid only),
// and its best exact cell replaces it.
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "st/common/progress.hpp"
#include "st/search/types.hpp"

namespace st::search {

/// A tree search's strongest candidates re-scored (searchWithChoice, searchTiled): the rest keep the tree's
/// cells.
inline constexpr std::size_t kPolishedTreeCandidates = 64;

struct PolishSummary {
  int rescored = 0;  ///< candidates searched again
  int moved = 0;     ///< whose best exact cell is another cell
  int dropped = 0;   ///< below the threshold in the exact statistic, or merged into another's cell
};

/// Replaces each of the first `maxCandidates` of result.candidates (the strongest; on every core) by its best
/// cell of the exact statistic over x +- 1, y +- 1 px and the grid cells within +- 2 steps of its velocity:
/// each cell's reference sum (ipsaReference, at the grid's own velocities), SNR = S / (sigma_F sqrt(N_in))
/// where N_in reaches result.minFrames; x, y, v, grid indices, S, N_in, SNR and FAP (result.trials) replaced,
/// clusterCells kept. A candidate whose best SNR is not above result.snrThreshold is dropped, and so is one
/// on the cell of a stronger re-scored one (or, not re-scored, on any re-scored one's cell). The candidates
/// are then in decreasing SNR, and those within the static-rate limit of cube.skyRate join
/// result.staticSources (setAsideStaticSources; one per cell, in decreasing SNR). The rest of `result` (the
/// tree's velocity map, the sidelobes merged) is left as the tree made it. Throws st::Cancelled.
PolishSummary polishTreeCandidates(const FilteredCube& cube, SearchResult& result, std::size_t maxCandidates,
                                   CancelToken& cancel);

/// The parts, for a search that holds the cube in pieces (searchTiled): candidate `c` (image pixels)
/// re-scored on `cube`, whose pixel (0, 0) is image pixel (x0, y0) and which holds every track of the window
/// (a tile's read area around its owned area); nullopt when its best exact cell is not above the threshold.
/// Uses result.grid, snrThreshold, minFrames and trials.
std::optional<Candidate> polishCandidate(const FilteredCube& cube, const SearchResult& result,
                                         const Candidate& c, int x0, int y0, CancelToken& cancel);
/// Puts polished[i] in place of result.candidates[i] (dropping those without one; candidates past
/// polished.size() are kept as they are), then orders, merges one cell's candidates and sets aside the static
/// ones as polishTreeCandidates does.
PolishSummary finishPolish(SearchResult& result, const std::vector<std::optional<Candidate>>& polished,
                           double psfFwhmPx, const TrackFrames& frames, Velocity skyRate);
/// The line of SearchResult::backendNote that says what the re-scoring did.
std::string polishNote(const PolishSummary& summary);

}  // namespace st::search

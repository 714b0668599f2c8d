#pragma once
// From cells above threshold to candidates: clustering of the cells of one object in (x, y, vx, vy) into
// one candidate at its best cell. Shared by every backend, so CPU and CUDA results cluster identically.
//
// Rule: two cells are neighbours when their positions at t_ref differ by at most `positionRadiusPx` in
// both x and y (default 2 x PSF FWHM: the position of a source at t_ref does not depend on the trial
// velocity, only its blur does) and their grid indices differ by at most `velocityRadiusSteps` in both vx
// and vy (default 2 steps). Connected cells form one candidate at their best cell, except that two
// connected peaks stay separate when the lower one rises above the best saddle between them by at least
// max(persistenceSnr, persistenceFraction x its peak): a noise bump on the ridge of a smeared source is
// merged, a faint object beside the skirts of a bright star is kept (plain single linkage would chain
// the two into one candidate and lose the object).
// Cost: cells are bucketed in (x, y, ivx, ivy) with sides no larger than the radii (the cells of one
// bucket are all neighbours) and the merging runs over buckets: O(cells) even for the ~1e6 cells of a
// bright source.
#include <cstdint>
#include <vector>

#include "st/search/types.hpp"

namespace st::search {

/// One (x, y, velocity) cell above threshold.
struct CellHit {
  float snr = 0.0f;  ///< S / (sigma_F sqrt(N_in))
  float sum = 0.0f;  ///< S
  int x = 0;         ///< column at t_ref
  int y = 0;         ///< row at t_ref
  int ivx = 0;       ///< grid index along vx
  int ivy = 0;       ///< grid index along vy
  int nIn = 0;       ///< frames that contributed
};

struct ClusterParams {
  double positionRadiusPx = 6.0;      ///< max |dx|, |dy| at t_ref for two cells to link (default 2 x FWHM)
  int velocityRadiusSteps = 2;        ///< max |d ivx|, |d ivy| for two cells to link
  double persistenceSnr = 2.0;        ///< a peak this far (SNR units) above its saddle stays separate...
  double persistenceFraction = 0.15;  ///< ...or this fraction of its own SNR, whichever is larger
};

/// The default linking radii for a PSF of this FWHM: 2 x FWHM (at least 2 px) and 2 grid steps.
ClusterParams defaultClusterParams(double psfFwhmPx);

/// Clusters `cells` and returns one candidate per cluster at its highest-SNR cell, sorted by decreasing
/// SNR, with Candidate::fap from the paper's Prob_false with `trials`, and clusterCells = cluster size.
std::vector<Candidate> clusterCells(const std::vector<CellHit>& cells, const VelocityGrid& grid,
                                    const ClusterParams& params, const TrialCounts& trials);

}  // namespace st::search

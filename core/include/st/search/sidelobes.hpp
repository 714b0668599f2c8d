#pragma once
// Sidelobes: a bright moving source also raises the IPSA sum at cells whose trial track crosses its own
// track for part of the span (another position at t_ref, another velocity). Those cells lie too far from
// the source in (x, y, v) to be clustered with it, and on top of noise some pass the threshold: on the demo
// (paper-neo, 45 x 45 velocities) the asteroid at SNR 15.9 brought two SNR ~7.1 candidates 10-15 px away
// whose tracks cross its own, of which the source explains SNR 2.3 and 3.9.
//
// Model: the matched-filtered frames answer a point source at offset d with K(d) / K(0), the autocorrelation
// of a Moffat PSF (beta 4, paper §3.3) of the filter's FWHM, tabulated numerically. A source found at
// cell b (x_b, y_b, v_b) with SNR_b, taken to sit at x_b + v_b dt_n, gives cell w the SNR
//   SNR_b x sqrt(N_b / N_w) x sum_{n in w} K(d_n) / sum_{n in b} K(e_n),
// d_n = (x_w + round(v_w dt_n), ...) - (x_b + v_b dt_n) and e_n the same for b's own cell (its rounding),
// both over the frames whose sample is inside the image (search/ipsa.hpp's shifts). A candidate is a
// sidelobe when its SNR less the largest such contribution of a brighter candidate is below the threshold:
// without that source it would not have been found. It is merged into that source (its cells counted in
// the source's clusterCells), as clustering merges the cells of one object.
#include <vector>

#include "st/search/types.hpp"

namespace st::search {

/// Closest approach (px) of two candidates' straight tracks (x + v t) over t in [t0, t1], seconds from t_ref.
[[nodiscard]] double closestApproach(const Candidate& a, const Candidate& b, double t0, double t1);

/// SNR that candidate `source` contributes to the cell of candidate `cell` (model above). `dtS` are
/// t_n - t_ref in seconds, `width` x `height` the frame size, `psfFwhmPx` the matched filter's PSF FWHM.
/// 0 when no frame of either track is inside the image.
[[nodiscard]] double sidelobeSnr(const Candidate& source, const Candidate& cell,
                                 const std::vector<double>& dtS, int width, int height, double psfFwhmPx);

/// Merges every candidate that is a sidelobe of a brighter one (model above) into it. `candidates` are
/// sorted by decreasing SNR and stay so. Pairs whose tracks never come within the distance where K falls
/// below 1e-3 (+1 px) over the span are skipped without evaluating the sums. Returns the number merged.
/// `offsets` are the frames' registration offsets (FrameCube::frameOffsets(); empty = all 0): a sample of
/// frame n is at round(o_n + v dt_n), a source at o_n + v dt_n.
std::size_t mergeSidelobes(std::vector<Candidate>& candidates, const std::vector<double>& dtS, int width,
                           int height, double psfFwhmPx, double snrThreshold,
                           const std::vector<PixelOffset>& offsets = {});

}  // namespace st::search

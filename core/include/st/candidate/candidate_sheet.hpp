#pragma once
// The stamps of a sheet of several candidates (issue 18 item 6, "a sheet of several candidates" as a figure
// source): for each candidate, the IPSA stamp of the search's matched-filtered cube at the candidate's own
// velocity, in SNR units (snrStampAt, the stamp the candidate inspector shows), and its centre SNR. The GUI
// lays the stamps out; the numbers come from here. Pure function of its input; no Qt.
#include <vector>

#include "st/candidate/inspection.hpp"
#include "st/common/progress.hpp"
#include "st/search/types.hpp"

namespace st::candidate {

struct SheetStamp {
  Image stamp;             ///< (2 half + 1)^2 pixels around (c.x, c.y), SNR units S / (sigma_F sqrt(N_in))
  double centreSnr = 0.0;  ///< the stamp's centre: the search statistic of the candidate's cell
  std::size_t nIn = 0;     ///< frames that contributed to the centre
};

/// One SheetStamp per candidate of `candidates`, in the same order, over all frames of `cube` at each
/// candidate's velocity. Throws st::InputError when the cube is empty, has no noise estimate (sigma_F <= 0)
/// or `half` < 1; st::Cancelled when `cancel` is raised (polled between candidates). Cost: per candidate,
/// frames x (2 half + 1)^2 additions.
[[nodiscard]] std::vector<SheetStamp> candidateSheetStamps(const search::FilteredCube& cube,
                                                           const std::vector<search::Candidate>& candidates,
                                                           int half, ProgressSink& progress,
                                                           CancelToken& cancel);

}  // namespace st::candidate

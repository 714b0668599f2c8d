#include "st/candidate/candidate_sheet.hpp"

#include <numeric>
#include <string>

#include "st/common/error.hpp"

namespace st::candidate {

std::vector<SheetStamp> candidateSheetStamps(const search::FilteredCube& cube,
                                             const std::vector<search::Candidate>& candidates, int half,
                                             ProgressSink& progress, CancelToken& cancel) {
  if (cube.frames.empty()) throw InputError("candidate sheet: the cube has no frames");
  if (!(cube.sigmaF > 0.0))
    throw InputError("candidate sheet: the filtered cube has no noise estimate (sigma_F = " +
                     std::to_string(cube.sigmaF) + ")");
  if (half < 1) throw InputError("candidate sheet: stamp half size must be >= 1, got " + std::to_string(half));
  std::vector<std::size_t> all(cube.frames.frameCount());
  std::iota(all.begin(), all.end(), std::size_t{0});
  std::vector<SheetStamp> out;
  out.reserve(candidates.size());
  for (std::size_t i = 0; i < candidates.size(); ++i) {
    cancel.throwIfCancelled();
    SnrStamp s = snrStampAt(cube, all, candidates[i], candidates[i].v, half);
    out.push_back({std::move(s.image), s.centreSnr, s.nIn});
    progress.report(static_cast<double>(i + 1) / static_cast<double>(candidates.size()), "candidate sheet");
  }
  return out;
}

}  // namespace st::candidate

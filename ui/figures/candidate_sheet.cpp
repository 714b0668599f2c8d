#include "candidate_sheet.hpp"

#include <algorithm>
#include <cmath>

#include "st/candidate/candidate_sheet.hpp"
#include "st/common/error.hpp"

namespace st::ui {

ImageFigure candidateSheetFigure(const search::FilteredCube& cube, const std::vector<SheetEntry>& entries,
                                 const CandidateSheetOptions& options, CancelToken& cancel) {
  if (entries.empty()) throw InputError("candidate sheet: no candidates chosen");
  const std::size_t n = std::min<std::size_t>(entries.size(), kMaxSheetPanels);
  std::vector<search::Candidate> candidates;
  for (std::size_t i = 0; i < n; ++i)
    candidates.push_back(entries[i].candidate);
  NullProgress progress;
  const int half = std::max(options.halfSizePx, 2);
  const auto stamps = candidate::candidateSheetStamps(cube, candidates, half, progress, cancel);

  ImageFigure fig;
  fig.columns = options.columns > 0 ? options.columns
                                    : static_cast<int>(std::ceil(std::sqrt(static_cast<double>(n))));
  for (std::size_t i = 0; i < n; ++i) {
    const SheetEntry& e = entries[i];
    ImagePanel p;
    p.image = std::make_shared<const Image>(stamps[i].stamp);
    std::tie(p.lo, p.hi) = computeLimits(p.image->data(), p.image->size(), options.display);
    // The candidate's own peak at the top of its bar (a zscale of a clean stamp stops far below it).
    p.hi = std::max(p.hi, stamps[i].centreSnr);
    if (!(p.hi > p.lo)) p.hi = p.lo + 1.0;
    p.display = options.display;
    p.origin = QPointF(e.candidate.x - half, e.candidate.y - half);  // axes in frame pixels
    p.title = QString("#%1  SNR %2  %3\n%4")
                  .arg(e.number)
                  .arg(stamps[i].centreSnr, 0, 'f', 1)
                  .arg(e.label, e.motion);
    p.units = options.units;
    p.plateScaleArcsecPerPx = options.plateScaleArcsecPerPx;
    p.showScaleBar = i == 0;
    p.showColourBar = options.colourBar;
    p.showAxes = options.axes;
    p.showCompass = false;
    fig.panels.push_back(std::move(p));
  }
  fig.title = QString("%1 candidates").arg(n);
  const QString more =
      entries.size() > n ? QString(" (the first %1 of %2 chosen)").arg(n).arg(entries.size()) : QString();
  fig.caption = QString(
                    "IPSA stacks of %1 frames over %2 s of the matched-filtered cube, each at its candidate's "
                    "velocity, in SNR units (S / (sigma_F sqrt(N_in))), %3 x %3 px around the candidate%4. "
                    "Rates are relative to the stars.")
                    .arg(cube.frames.frameCount())
                    .arg(cube.frames.timeSpanS(), 0, 'f', 1)
                    .arg(2 * half + 1)
                    .arg(more);
  return fig;
}

}  // namespace st::ui

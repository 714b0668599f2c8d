#pragma once
// "A sheet of several candidates" (issue 18 item 6) as a figure: a grid of one panel per candidate, each the
// IPSA stamp of the search's matched-filtered cube at the candidate's velocity in SNR units (the stamps and
// their numbers come from core: st::candidate::candidateSheetStamps), titled with the candidate's number,
// SNR, label and its rate relative to the stars in the Search dock's unit (motion_vs_sky.hpp, computed by
// the caller on the GUI thread). This file only lays the panels out. Heavy enough for a worker thread.
#include <QString>
#include <optional>
#include <vector>

#include "figure_render.hpp"
#include "image_render.hpp"
#include "st/common/progress.hpp"
#include "st/search/types.hpp"

namespace st::ui {

/// One candidate of the sheet, as the GUI names it.
struct SheetEntry {
  int number = 0;  ///< 1-based, as in the candidates table
  search::Candidate candidate;
  QString motion;  ///< describeMotion(motionVsSky(...)): "rate 12.3 deg/day vs sky, PA 245.1°"
  QString label;   ///< the vetting label's key ("real", "unvetted", ...)
};

struct CandidateSheetOptions {
  int halfSizePx = 12;  ///< each stamp is (2 halfSize + 1)^2 pixels (clipped to nothing: out-of-frame is 0)
  int columns = 0;      ///< 0: ceil(sqrt(n)), a near-square grid
  DisplaySettings display;
  std::optional<double> plateScaleArcsecPerPx;  ///< scale bar on the first panel
  QString units = "SNR";
  bool colourBar = true;
  bool axes = true;
};

/// At most this many panels on one sheet (more would be unreadable on a page); the caption says when the
/// sheet shows the first kMaxSheetPanels of more.
inline constexpr int kMaxSheetPanels = 64;

/// The sheet of `entries` (at most kMaxSheetPanels are drawn, in the given order) over `cube`. Each panel's
/// display limits are its own (computeLimits with options.display): candidates of very different SNR stay
/// visible, and each colour bar gives its scale; the top of each bar is at least the candidate's SNR. Throws st::InputError from core (no cube, no sigma_F) or
/// for an empty list; st::Cancelled when cancelled.
[[nodiscard]] ImageFigure candidateSheetFigure(const search::FilteredCube& cube,
                                               const std::vector<SheetEntry>& entries,
                                               const CandidateSheetOptions& options, CancelToken& cancel);

}  // namespace st::ui

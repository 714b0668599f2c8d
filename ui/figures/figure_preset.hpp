#pragma once
// The paper's figure fig_st_sky_and_nea (Zhai et al. 2014, §5.1): two IPSA synthetic-tracking images of the
// same patch, one tracking the object (it is a sharp point, an arrow points at it) beside one tracking the
// stars (the object streaks and its surface brightness drops below the noise; an arrow along the streak
// shows the motion). Both panels share the display limits, so the trailing loss is visible as it is.
// Computing the stacks is heavy (a full IPSA sum per panel): call this from a worker thread.
#include <QString>
#include <optional>

#include "figure_render.hpp"
#include "image_render.hpp"
#include "st/search/types.hpp"

namespace st::ui {

struct SkyAndObjectOptions {
  int halfSizePx = 40;  ///< each stamp is (2 halfSize + 1)^2 pixels around the candidate (clipped)
  DisplaySettings display;
  std::optional<double> plateScaleArcsecPerPx;  ///< scale bar, and rates in deg/day in the caption
  std::optional<Compass> compass;
  QString units = "IPSA sum";
  int candidateNumber = 1;  ///< 1-based, for the caption
  /// The object's motion as the GUI shows it (relative to the stars, in the Search dock's unit:
  /// describeMotion() of motion_vs_sky.hpp), for the caption; empty: deg/day from the plate scale.
  QString motion;
  QString snrLabel = "SNR";  ///< what the title's SNR is: "fit SNR" or "search SNR"
};

/// The figure for candidate `c` of `cube`: left, the IPSA stack at c.v; right, the IPSA stack at `skyRate`
/// (st::stack::stackIpsa, the same positions at t_ref), cropped around (c.x, c.y). Display limits are those
/// of the object-tracked stamp. Arrows: in the left panel from 1.5 FWHM + 8 px above the object down to
/// 1.5 FWHM + 1 px above it; in the right panel along the streak, from the object's position at the first
/// frame to the last ((v - skyRate) dt_n), offset sideways by 2 FWHM + 2 px. Throws st::InputError for an
/// empty cube or a candidate outside it.
[[nodiscard]] ImageFigure skyAndObjectFigure(const search::FilteredCube& cube, const search::Candidate& c,
                                             Velocity skyRate, const SkyAndObjectOptions& options);

}  // namespace st::ui

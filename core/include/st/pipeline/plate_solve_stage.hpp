#pragma once
// Plate solving as a pipeline step (issue 15 item 5): the WCS of a cube whose frames have none, from the
// pre-processing's static-source catalogue (stars found in the sky-rate stack) or from the sources of one
// frame, through astro::plateSolve (astrometry.net). The solution is used like a header WCS: it maps the
// pixels of the cube's FIRST frame (FrameCube::wcs), so writers, RA/Dec, the compass and ADES take it as is.
#include <memory>
#include <optional>
#include <vector>

#include "st/astro/plate_solve.hpp"
#include "st/common/frame_cube.hpp"
#include "st/common/progress.hpp"
#include "st/common/units.hpp"
#include "st/detect/static_sources.hpp"
#include "st/io/xylist.hpp"

namespace st::pipeline {

struct Prepared;

/// The catalogue's stars (positions at t_ref) where they lie in the cube's first frame: x + v (t_0 - t_ref)
/// + o_0 (ARCHITECTURE.md, registration), flux as catalogued. Stars outside the first frame are left out.
std::vector<io::XyStar> firstFrameStars(const std::vector<detect::Star>& stars, const FrameCube& cube,
                                        Velocity skyRate);

/// Sources of the cube's first frame alone (detect::findStaticSources on a one-frame cube, its sigma-clipped
/// mean as the background), for frames that are not pre-processed (`synthtrack-cli solve`). 0-based px.
std::vector<io::XyStar> frameStars(const FrameCube& cube, ProgressSink& progress, CancelToken& cancel);

/// Solves `cube`'s WCS from `stars` (first-frame pixels) and sets cube.wcs and cube.plateScaleArcsecPerPx.
/// Hints missing from `params` are taken from cube.header (astro::plateSolveHints) and from
/// cube.plateScaleArcsecPerPx. Throws as astro::plateSolve.
astro::PlateSolution plateSolveCube(FrameCube& cube, const std::vector<io::XyStar>& stars,
                                    astro::PlateSolveParams params, ProgressSink& progress,
                                    CancelToken& cancel);

/// Gives `cube` the WCS `wcs` as if its header had it: cube.wcs, cube.plateScaleArcsecPerPx, and the header's
/// WCS cards replaced by wcs->toHeader()'s, so that calibration's trim (which moves CRPIX) and every later
/// stage carry it like a header WCS. A null `wcs` changes nothing.
void attachHeaderWcs(FrameCube& cube, std::shared_ptr<const Wcs> wcs,
                     std::optional<double> plateScaleArcsecPerPx);

/// Plate-solves the first frame of a cube not yet calibrated (frameStars, then plateSolveCube) and writes the
/// solution into cube.header as WCS cards (replacing any), so that calibration's trim (which moves CRPIX)
/// and every later stage carry it exactly like a header WCS. Throws as astro::plateSolve.
astro::PlateSolution plateSolveRawCube(FrameCube& cube, const astro::PlateSolveParams& params,
                                       ProgressSink& progress, CancelToken& cancel);

/// plateSolveCube on a pre-processed cube from its static-source catalogue (prepared.stars at
/// prepared.skyRate); prepared.filtered.frames gets the same WCS; a note saying what was solved is appended
/// to prepared.notes.
astro::PlateSolution plateSolvePrepared(Prepared& prepared, const astro::PlateSolveParams& params,
                                        ProgressSink& progress, CancelToken& cancel);

/// One line for the user: centre, scale, index, stars, time.
std::string describeSolution(const astro::PlateSolution& solution);

}  // namespace st::pipeline

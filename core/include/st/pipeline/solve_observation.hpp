#pragma once
// Plate solving of an observation as the GUI holds it (issue 15 item 5, "Plate solve" in the GUI): the loaded
// frames, and the pre-processing's static-source catalogue when it ran. Unlike plateSolveCube it leaves the
// cubes alone and returns the solution: the GUI holds its cube once, shared with running stack workers, and
// attaches the WCS itself on its GUI thread. Same star lists and hints as `synthtrack-cli preprocess
// --plate-solve` (plate_solve_stage.hpp).
#include <string>
#include <vector>

#include "st/astro/plate_solve.hpp"
#include "st/common/frame_cube.hpp"
#include "st/common/progress.hpp"
#include "st/common/units.hpp"
#include "st/detect/static_sources.hpp"

namespace st::pipeline {

struct ObservationSolveInput {
  /// The frames as loaded (required): header hints (plateSolveHints), its plate scale as a hint, and the
  /// sources of its first frame when there is no catalogue.
  const FrameCube* raw = nullptr;
  /// The pre-processing's static-source catalogue (positions at t_ref) and the cube its pixels refer to
  /// (the pre-processed frames); used when it holds at least 4 stars inside the first frame.
  const std::vector<detect::Star>* catalogue = nullptr;
  const FrameCube* catalogueFrames = nullptr;
  Velocity skyRate;  ///< of the catalogue (firstFrameStars)
};

struct ObservationSolve {
  astro::PlateSolution solution;  ///< solution.wcs maps the first frame's 0-based pixels
  std::string starSource;         ///< "N stars of the static-source catalogue" or "N sources of frame 0"
  std::string summary;            ///< describeSolution() and the star source, one line
};

/// Solves the observation's WCS through astro::plateSolve. Hints missing from `params` come from the raw
/// header and raw plate scale. Throws st::InputError without raw frames, and as astro::plateSolve (solve-field
/// missing: names the package; no index files; its stderr; no solution in the time limit); st::Cancelled.
[[nodiscard]] ObservationSolve plateSolveObservation(const ObservationSolveInput& input,
                                                     astro::PlateSolveParams params, ProgressSink& progress,
                                                     CancelToken& cancel);

}  // namespace st::pipeline

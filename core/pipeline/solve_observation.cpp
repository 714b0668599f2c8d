#include "st/pipeline/solve_observation.hpp"

#include "st/common/error.hpp"
#include "st/pipeline/plate_solve_stage.hpp"

namespace st::pipeline {

ObservationSolve plateSolveObservation(const ObservationSolveInput& in, astro::PlateSolveParams params,
                                       ProgressSink& progress, CancelToken& cancel) {
  if (!in.raw || in.raw->empty()) throw InputError("plate solve: no frames are loaded");
  const FrameCube& raw = *in.raw;
  if (!params.scaleArcsecPerPx && raw.plateScaleArcsecPerPx) params.scaleArcsecPerPx = raw.plateScaleArcsecPerPx;
  astro::applyHints(params, astro::plateSolveHints(raw.header));
  ObservationSolve out;
  std::vector<io::XyStar> stars;
  const FrameCube* geometry = &raw;
  if (in.catalogue && in.catalogueFrames && !in.catalogueFrames->empty()) {
    stars = firstFrameStars(*in.catalogue, *in.catalogueFrames, in.skyRate);
    geometry = in.catalogueFrames;
    out.starSource = std::to_string(stars.size()) + " stars of the static-source catalogue";
  }
  if (stars.size() < 4) {
    progress.report(0.0, "finding the first frame's sources");
    stars = frameStars(raw, progress, cancel);
    geometry = &raw;
    out.starSource = std::to_string(stars.size()) + " sources of frame 0";
  }
  cancel.throwIfCancelled();
  progress.report(0.05, "plate solving (astrometry.net solve-field)");
  out.solution = astro::plateSolve(stars, geometry->width(), geometry->height(), params, progress, cancel);
  out.summary = describeSolution(out.solution) + "; from " + out.starSource;
  return out;
}

}  // namespace st::pipeline

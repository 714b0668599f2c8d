#include "st/pipeline/registration_stage.hpp"

#include <sstream>

namespace st::pipeline {

bool registerFramesStage(Prepared& out, FrameCube& cube, const PreprocessParams& params, ProgressSink& progress,
                         CancelToken& cancel, std::size_t* framesMoved) {
  if (framesMoved) *framesMoved = 0;
  if (params.givenRegistration) {
    detect::applyRegistration(cube, *params.givenRegistration);
    out.registration = *params.givenRegistration;
    return false;  // the rate, when it came from this registration, is given as params.skyRate
  }
  if (!params.registerFrames) {
    detect::applyRegistration(cube, {});
    out.registration = {};
    return false;
  }
  detect::Registration reg = detect::measureRegistration(cube, params.skyRate, params.registration, progress, cancel);
  out.notes.push_back(reg.note);
  if (params.registration.alignWholePixels) {
    const std::size_t moved = detect::alignWholePixels(cube, reg, cancel);
    if (framesMoved) *framesMoved = moved;
    if (moved > 0) {
      out.notes.push_back("registration: " + std::to_string(moved) +
                          " frame(s) moved by whole pixels onto the first frame's pixel grid for the per-pixel "
                          "stages (the pixels they uncover masked), and back onto their own after the matched "
                          "filter");
    }
  }
  detect::applyRegistration(cube, reg);
  const bool perFrame = reg.model == detect::Registration::Model::PerFrame;
  if (perFrame && !params.skyRate) {
    out.skyRate = reg.rate;
    out.skyRateMeasured = true;
    std::ostringstream note;
    note << "sky rate from the registered star field (" << reg.rateNote << "): (" << reg.rate.vx << ", "
         << reg.rate.vy << ") px/s";
    out.notes.push_back(note.str());
  }
  out.registration = std::move(reg);
  return perFrame && !params.skyRate;
}

}  // namespace st::pipeline

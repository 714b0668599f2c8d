#include "st/pipeline/registration_stage.hpp"

#include <sstream>

#include "st/common/error.hpp"

#include "st/pipeline/preprocess_accelerator.hpp"

namespace st::pipeline {

bool registerFramesStage(Prepared& out, FrameCube& cube, const PreprocessParams& params,
                         ProgressSink& progress, CancelToken& cancel, std::size_t* framesMoved) {
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
  // A device's download of the frame backgrounds' frames may still run (issue 16): each frame is waited
  // for before it is read, every frame before any is written.
  // The long sequences' sampled links on the device when it takes them, from the frames it kept.
  PreprocessAccelerator* accel = params.accelerator;
  detect::RegistrationHooks hooks;
  std::string linksFailed;
  if (accel) {
    hooks.gate = [accel, &cube](std::size_t n) { accel->waitForHostFrames(cube, n, n + 1); };
    hooks.links = [accel, &linksFailed](const FrameCube& c, const detect::RegistrationLinkBatch& batch)
        -> std::optional<std::vector<detect::RegistrationLinkPeak>> {
      try {
        return accel->registrationLinks(c, batch);
      } catch (const GpuError& e) {
        linksFailed = e.what();
        return std::nullopt;
      }
    };
  }
  detect::Registration reg =
      detect::measureRegistration(cube, params.skyRate, params.registration, progress, cancel, hooks);
  if (reg.linksElsewhere > 0) out.notes.push_back(accel->lastNote());
  if (!linksFailed.empty())
    out.notes.push_back("warning: registration's sampled links fell back to the CPU (" + accel->name() +
                        ": " + linksFailed + ")");
  out.notes.push_back(reg.note);
  if (params.registration.alignWholePixels) {
    // It moves frames only under the per-frame model: every frame must be on the host first.
    if (accel && reg.model == detect::Registration::Model::PerFrame) accel->finishHostCopies();
    const std::size_t moved = detect::alignWholePixels(cube, reg, cancel);
    if (framesMoved) *framesMoved = moved;
    if (moved > 0) {
      out.notes.push_back(
          "registration: " + std::to_string(moved) +
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

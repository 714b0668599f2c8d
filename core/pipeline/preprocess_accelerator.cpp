#include "st/pipeline/preprocess_accelerator.hpp"

#include "st/common/error.hpp"

namespace st::pipeline {
namespace {

std::string fallbackNote(const PreprocessAccelerator& accel, const char* stage, const GpuError& e) {
  return std::string("warning: the ") + stage + " on " + accel.name() + " failed (" + e.what() +
         "); the CPU did it instead";
}

}  // namespace

stats::ClipStats globalBackgroundOn(PreprocessAccelerator* accel, const FrameCube& cube,
                                    const stats::GlobalBackgroundParams& params,
                                    std::vector<std::string>& notes) {
  if (accel) {
    try {
      return accel->globalBackground(cube, params);
    } catch (const GpuError& e) {
      notes.push_back(fallbackNote(*accel, "global background", e));
    }
  }
  return stats::globalBackground(cube, params);
}

double removeResidualMeansOn(PreprocessAccelerator* accel, FrameCube& cube, int meshPx, double clipSigma,
                             ProgressSink& progress, CancelToken& cancel, std::vector<std::string>& notes) {
  if (accel) {
    try {
      const double rms = accel->removeResidualMeans(cube, meshPx, clipSigma, progress, cancel);
      if (!accel->lastNote().empty()) notes.push_back(accel->lastNote());
      return rms;
    } catch (const GpuError& e) {
      notes.push_back(fallbackNote(*accel, "residual means", e));
    }
  }
  return stats::removeResidualMeans(cube, meshPx, clipSigma, progress, cancel);
}

stats::Background subtractPixelBackgroundOn(PreprocessAccelerator* accel, FrameCube& cube,
                                            const stats::BackgroundParams& params,
                                            const detect::MovingMask* exclude, ProgressSink& progress,
                                            CancelToken& cancel, std::vector<std::string>& notes) {
  if (accel) {
    try {
      stats::Background out = accel->subtractPixelBackground(cube, params, exclude, progress, cancel);
      if (!accel->lastNote().empty()) notes.push_back(accel->lastNote());
      return out;
    } catch (const GpuError& e) {
      notes.push_back(fallbackNote(*accel, "per-pixel background", e));
    }
  }
  return stats::subtractPixelBackground(cube, params, exclude, progress, cancel);
}

stack::MatchedFilterResult filterCubeOn(PreprocessAccelerator* accel, FrameCube& cube,
                                        const stack::FilterKernel& kernel, ProgressSink& progress,
                                        CancelToken& cancel, const stats::NoiseModel* noise,
                                        std::vector<std::string>& notes, std::uint64_t revision) {
  if (accel) {
    try {
      stack::MatchedFilterResult out = accel->filterCube(cube, kernel, progress, cancel, noise, revision);
      if (!accel->lastNote().empty()) notes.push_back(accel->lastNote());
      return out;
    } catch (const GpuError& e) {
      notes.push_back(fallbackNote(*accel, "matched filter", e));
    }
  }
  return stack::filterCube(cube, kernel, progress, cancel, noise);
}

stack::MatchedFilterResult filterCubeFromOn(PreprocessAccelerator* accel, const FrameCube& source,
                                            FrameCube& filtered, const stack::FilterKernel& kernel,
                                            ProgressSink& progress, CancelToken& cancel,
                                            const stats::NoiseModel* noise, std::vector<std::string>& notes,
                                            std::uint64_t revision) {
  if (accel) {
    try {
      stack::MatchedFilterResult out =
          accel->filterCubeFrom(source, filtered, kernel, progress, cancel, noise, revision);
      if (!accel->lastNote().empty()) notes.push_back(accel->lastNote());
      return out;
    } catch (const GpuError& e) {
      notes.push_back(fallbackNote(*accel, "matched filter", e));
    }
  }
  filtered.pixels() = source.pixels();
  filtered.mask().clear();
  return stack::filterCube(filtered, kernel, progress, cancel, noise);
}

}  // namespace st::pipeline

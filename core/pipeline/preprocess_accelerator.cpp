#include "st/pipeline/preprocess_accelerator.hpp"

#include <chrono>

#include "st/calib/cosmic_rays.hpp"
#include "st/common/error.hpp"

namespace st::pipeline {
namespace {

// The warning for a stage the device failed, once the device's downloads into the host cubes are done (the
// CPU then does the stage on them).
std::string fallbackNote(PreprocessAccelerator& accel, const char* stage, const GpuError& e) {
  accel.finishHostCopies();
  return std::string("warning: the ") + stage + " on " + accel.name() + " failed (" + e.what() +
         "); the CPU did it instead";
}

}  // namespace

stats::FrameBackgrounds removeFrameBackgroundsOn(PreprocessAccelerator* accel, FrameCube& cube,
                                                 const stats::FrameBackgroundParams& params,
                                                 ProgressSink& progress, CancelToken& cancel,
                                                 std::vector<std::string>& notes) {
  if (accel) {
    try {
      stats::FrameBackgrounds out = accel->removeFrameBackgrounds(cube, params, progress, cancel);
      if (!accel->lastNote().empty()) notes.push_back(accel->lastNote());
      return out;
    } catch (const GpuError& e) {
      notes.push_back(fallbackNote(*accel, "frame backgrounds", e));
    }
  }
  return stats::removeFrameBackgrounds(cube, params, progress, cancel);
}

stats::FrameBackgrounds calibrateAndRemoveFrameBackgroundsOn(PreprocessAccelerator* accel, FrameCube& cube,
                                                             const calib::CalibrationPlan& plan,
                                                             const stats::FrameBackgroundParams& params,
                                                             ProgressSink& progress, CancelToken& cancel,
                                                             std::vector<std::string>& notes) {
  if (accel) {
    try {
      std::optional<stats::FrameBackgrounds> out =
          accel->calibrateAndRemoveFrameBackgrounds(cube, plan, params, progress, cancel);
      if (out) {
        if (!accel->lastNote().empty()) notes.push_back(accel->lastNote());
        return std::move(*out);
      }
    } catch (const GpuError& e) {
      notes.push_back(fallbackNote(*accel, "calibration and frame backgrounds", e));
      accel = nullptr;  // the backgrounds on the CPU too
    }
  }
  calib::applyPixelCalibration(cube, plan, progress, cancel);
  return removeFrameBackgroundsOn(accel, cube, params, progress, cancel, notes);
}

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

std::vector<std::size_t> findHotPixelsOn(PreprocessAccelerator* accel, const FrameCube& cube,
                                         const stats::ClipStats& global, const detect::HotPixelParams& params,
                                         CancelToken& cancel, std::vector<std::string>& notes) {
  if (accel) {
    try {
      if (const auto excess = accel->hotPixelExcess(cube, global.mean, params))
        return detect::hotPixelsFromExcess(*excess, cube.width(), cube.height(), cube.frameCount(),
                                           global.sigma, params);
    } catch (const GpuError& e) {
      notes.push_back(fallbackNote(*accel, "hot pixels", e));
    }
    accel->finishHostCopies();  // the CPU reads the host frames
  }
  return detect::findHotPixels(cube, global.mean, global.sigma, params, cancel);
}

stats::NoiseModel estimateNoiseModelOn(PreprocessAccelerator* accel, const FrameCube& zeroBiased,
                                       const Image& pixelSigma, const std::vector<std::uint8_t>& unmeasured,
                                       const stats::NoiseModelParams& params, CancelToken& cancel,
                                       std::vector<std::string>& notes) {
  if (accel) {
    try {
      stats::NoiseModel out = accel->estimateNoiseModel(zeroBiased, pixelSigma, unmeasured, params, cancel);
      if (!accel->lastNote().empty()) notes.push_back(accel->lastNote());
      return out;
    } catch (const GpuError& e) {
      notes.push_back(fallbackNote(*accel, "noise model", e));
    }
  }
  return stats::estimateNoiseModel(zeroBiased, pixelSigma, unmeasured, params, cancel);
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

ZeroBiasResult zeroBiasStages(PreprocessAccelerator* accel, FrameCube& cube, const ZeroBiasInputs& in,
                              ProgressSink& progress, CancelToken& cancel, std::vector<std::string>& notes) {
  ZeroBiasResult out;
  auto last = std::chrono::steady_clock::now();
  auto lap = [&](const char* stage) {
    const auto now = std::chrono::steady_clock::now();
    out.stageSeconds.emplace_back(stage, std::chrono::duration<double>(now - last).count());
    last = now;
  };
  {
    SubProgress sub(progress, 0.4, 0.65);
    out.background = subtractPixelBackgroundOn(accel, cube, in.background, in.exclude, sub, cancel, notes);
  }
  lap("per-pixel background");
  out.starsAttempted = in.subtractRegion && !in.subtractRegion->empty();
  if (out.starsAttempted) {
    // Before the cosmic-ray pixels are zeroed: they hold their time neighbours' values until then.
    SubProgress sub(progress, 0.65, 0.75);
    out.starSubtraction = detect::subtractStarTemplate(cube, *in.subtractRegion, &out.background.sigma,
                                                       in.starSubtraction, sub, cancel);
    if (out.starSubtraction.applied && in.starMask) {
      // The sky positions whose residuals vary too much are masked with the cores.
      in.starMask->add(out.starSubtraction.excess);
    }
    lap("star subtraction");
  }
  if (in.cosmicRayPixels) calib::zeroPixels(cube, *in.cosmicRayPixels);
  {
    SubProgress sub(progress, 0.75, 0.8);
    const MovingMask none;
    const MovingMask& movers = in.moverMask ? *in.moverMask : none;
    if (in.starMask) out.staticPixelsZeroed = detect::zeroMasked(cube, *in.starMask, sub, cancel);
    if (out.starsAttempted && !out.starSubtraction.applied)
      out.staticPixelsZeroed += detect::zeroMasked(cube, *in.subtractRegion, sub, cancel);
    out.unmeasuredPixelsZeroed = detect::zeroUnmeasured(cube, out.background.filled, movers);
    out.singleFrame =
        detect::zeroSingleFrameSources(cube, out.background.sigma, out.background.sigmaN, in.singleFrameSnr,
                                       in.singleFrameRadiusPx, sub, cancel, &movers);
  }
  lap("zeroing");  // cosmic-ray pixels, masks, unmeasured pixels, single-frame sources
  if (in.removeResidualMean) {
    SubProgress sub(progress, 0.8, 0.83);
    out.residualMeanRms =
        removeResidualMeansOn(accel, cube, in.residualMeshPx, in.residualClipSigma, sub, cancel, notes);
  }
  lap("residual means");
  return out;
}

ZeroBiasResult zeroBiasOn(PreprocessAccelerator* accel, FrameCube& cube, const ZeroBiasInputs& in,
                          ProgressSink& progress, CancelToken& cancel, std::vector<std::string>& notes) {
  if (accel) {
    const MovingMask starMask = in.starMask ? *in.starMask : MovingMask();
    try {
      ZeroBiasResult out;
      if (accel->zeroBias(cube, in, out, progress, cancel)) {
        if (!accel->lastNote().empty()) notes.push_back(accel->lastNote());
        return out;
      }
    } catch (const GpuError& e) {
      notes.push_back(fallbackNote(*accel, "per-pixel background to residual means", e));
      if (in.starMask) *in.starMask = starMask;
    }
  }
  return zeroBiasStages(accel, cube, in, progress, cancel, notes);
}

}  // namespace st::pipeline

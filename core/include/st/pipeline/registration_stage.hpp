#pragma once
// The registration stage of pre-processing (detect/registration.hpp), run after calibration, the frames'
// own backgrounds and the hot pixels, before the sky rate: it writes the frames' registration offsets
// (FrameInfo::offsetXPx/offsetYPx, used by every later stage and by the search) and, when the per-frame
// model is used, the sky rate, so that the block-stack sky-rate measurement (which assumes a linear motion)
// is not asked to follow dithers.
#include "st/common/frame_cube.hpp"
#include "st/common/progress.hpp"
#include "st/detect/registration.hpp"
#include "st/pipeline/preprocess.hpp"

namespace st::pipeline {

/// Measures and applies the registration of `cube` when params.registerFrames (else clears any offsets and
/// returns Unmeasured). Notes the model and its rms in out.notes; sets out.skyRate (and
/// out.skyRateMeasured) and returns true when the per-frame model is used and no sky rate was given.
/// `framesMoved` (optional): the frames whose pixels were moved by whole pixels (0: the pixels are as they
/// were; only the frame info changed).
bool registerFramesStage(Prepared& out, FrameCube& cube, const PreprocessParams& params, ProgressSink& progress,
                         CancelToken& cancel, std::size_t* framesMoved = nullptr);

}  // namespace st::pipeline

#pragma once
// Raw frames on disk pre-processed out of core (issue 20): the front end that the CLI (`search`, `batch`)
// and the GUI call when an observation's in-memory pre-processing does not fit the memory budget. It plans
// the strips of rows (planOutOfCorePreprocess), builds the calibration masters once for the whole frame and
// crops them to each strip, reads each strip with CFITSIO's subset reader (io::loadFrames with a crop) and
// runs pipeline::preprocessOutOfCore into a filtered cube in a scratch folder, which is then searched as a
// pre-processed cube (in memory or in tiles, search/tiled_search.hpp).
//
// Two steps, so that a front end can show the plan (and its estimate) before any pixel is read:
// planRawOutOfCore (no pixel read; throws st::InputError naming the need and the budget when not even the
// smallest strip fits), then preprocessRawOutOfCore.
#include <optional>
#include <string>
#include <vector>

#include "st/calib/calibration.hpp"
#include "st/common/frame_cube.hpp"
#include "st/common/memory_budget.hpp"
#include "st/common/progress.hpp"
#include "st/io/fits_reader.hpp"
#include "st/pipeline/memory_plan.hpp"
#include "st/pipeline/preprocess_out_of_core.hpp"

namespace st::pipeline {

/// One raw observation on disk: science frames (files or folders), how they are loaded (the user's crop,
/// clock), and the calibration frames with the calibration choices.
struct RawObservationFiles {
  std::vector<std::string> inputs;
  io::LoadOptions load;
  std::vector<std::string> bias, dark, flat;
  calib::CalibParams calib;
};

/// Loads bias, dark or flat frames (files or folders; none = an empty cube) with a nominal clock, no
/// science-frame warnings, cropped with `crop` as the science frames are (so that the masters match them).
FrameCube loadCalibrationFrames(const std::vector<std::string>& files, const std::optional<io::CropRegion>& crop,
                                ProgressSink& progress, CancelToken& cancel);

struct RawOutOfCoreOptions {
  bool registerFrames = true;    ///< per-frame registration (PreprocessParams::registerFrames)
  std::string scratchDir = ".";  ///< where the filtered cube is written
  /// Keep the cube: it is named STEM.synthtrack-filtered.fits after the first input; otherwise
  /// STEM.synthtrack-filtered.PID.fits (two runs in one folder never overwrite each other's), and the
  /// caller removes it when done.
  bool keepScratch = false;
};

/// The plan of an out-of-core pre-processing, made before any pixel is read.
struct RawOutOfCorePlan {
  CubeShape shape;                     ///< the raw frames (before trimming)
  PreprocessParams params;             ///< calibration choices, registration, no zero-biased copy
  OutOfCorePreprocessPlan strips;      ///< non-empty
  std::optional<calib::Section> trim;  ///< the frame's trim region (calib::trimRegion), raw-frame coordinates
  std::string path;                    ///< the filtered cube to write
  std::string description;             ///< "pre-processing out of core: N strips of up to ... estimated peak ..."
  std::vector<std::string> warnings;   ///< trim-region warnings (said once for the frame)
};

/// Plans the pre-processing of `files` (`summary` from io::summarizeInputs with files.load) in strips under
/// `budget` with `threads` workers. Reads headers only. Throws st::InputError (pipeline::overBudgetMessage)
/// when not even the smallest strip (64 rows plus the overlaps) fits.
RawOutOfCorePlan planRawOutOfCore(const RawObservationFiles& files, const io::InputSummary& summary,
                                  const RawOutOfCoreOptions& options, const MemoryBudget& budget, unsigned threads);

/// Runs `plan`: the masters once for the whole frame (checked against the first frame's header and size),
/// then preprocessOutOfCore with each strip read by CFITSIO's subset reader and the masters cropped to it.
/// The cube is at plan.path (removed again when this throws); the result's warnings start with the plan's
/// and the calibration frames'. Throws what loading, calibration and preprocessOutOfCore throw
/// (st::InputError for an already pre-processed input, st::FitsError, st::Cancelled).
OutOfCorePrepared preprocessRawOutOfCore(const RawObservationFiles& files, const io::InputSummary& summary,
                                         const RawOutOfCorePlan& plan, ProgressSink& progress,
                                         CancelToken& cancel);

}  // namespace st::pipeline

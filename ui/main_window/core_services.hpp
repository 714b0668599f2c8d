#pragma once
// What the GUI needs from the core, as plain functions the application fills in (app/gui/core_adapter.cpp).
// The GUI never re-implements science: it calls these from worker threads and shows the results. Keeping
// them behind one struct lets tests inject small fakes and keeps st_ui free of st_gpu (a backend is made by
// the application's factory and handed in).
#include <functional>
#include <nlohmann/json.hpp>

#include "st/candidate/candidate_measurement.hpp"
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "st/common/frame_cube.hpp"
#include "st/common/image.hpp"
#include "st/common/progress.hpp"
#include "st/fit/comoving_fit.hpp"
#include "st/pipeline/out_of_core_cube.hpp"
#include "st/pipeline/preprocess.hpp"
#include "st/search/types.hpp"
#include "st/session/preprocess_settings.hpp"

namespace st::ui {

/// One numeric parameter of a pre-processing stage, with its default (the paper's value) and range.
struct StageParam {
  std::string key;    ///< identifier the adapter maps onto the typed core parameter struct
  std::string label;  ///< shown to the user
  std::string unit;   ///< e.g. "px", "sigma"
  double value = 0.0;
  double minimum = 0.0;
  double maximum = 1e9;
  int decimals = 2;
  std::string help;  ///< tooltip: what it does and where the default comes from
};

/// Files or folders a stage reads, e.g. the calibration's bias, flat and dark frames (several allowed).
struct StageFiles {
  std::string key;                 ///< identifier the adapter maps onto the core call ("bias", "flat", "dark")
  std::string label;               ///< shown to the user
  std::vector<std::string> paths;  ///< files and/or folders (absolute); empty = none
  std::string help;                ///< tooltip
};

/// A pre-processing stage as the panel shows it: name, on/off, parameters, file lists.
struct StageSpec {
  std::string name;  ///< shown to the user
  bool enabled = true;
  bool optional = true;  ///< false: the stage cannot be switched off
  std::vector<StageParam> params;
  std::vector<StageFiles> files;  ///< stored in sessions beside the parameters
  /// Stable key (session::preprocessStageSpecs: "cosmic_rays"): what session files store; "" = the name.
  std::string key;
  /// Keys older session files used for this stage (format 2 stored the display name).
  std::vector<std::string> formerKeys;
  std::string help;  ///< what the stage does (the group's tooltip)
};

/// The paths of `stages`' file list `key` (first match), empty when there is none.
std::vector<std::string> stageFiles(const std::vector<StageSpec>& stages, const std::string& key);

/// The core's pre-processing stages (session::preprocessStageSpecs) at their defaults, as the panel shows
/// them.
std::vector<StageSpec> describedStages();
/// The stages' on/off and values by stable key, for session::preprocessParams (stages without a key are left
/// out: test fakes).
session::PreprocessSettings preprocessSettings(const std::vector<StageSpec>& stages);
/// Whether the stage with stable key `key` is on (true when there is none).
bool stageEnabled(const std::vector<StageSpec>& stages, const std::string& key);

/// What pre-processing produced, as the GUI shows it.
struct PreparedView {
  /// The matched-filtered frames the search runs on (null when not produced).
  std::shared_ptr<const search::FilteredCube> filtered;
  /// The same frames before the matched filter (zero-biased, static sources removed), for "unfiltered"
  /// stacks. May be null when the pipeline does not keep them.
  std::shared_ptr<const search::FilteredCube> unfiltered;
  /// Named intermediate images: "calibrated (frame 0)", "background", "noise", "static-source mask", ...
  std::vector<std::pair<std::string, Image>> layers;
  /// One-line summary: noise, PSF, number of masked stars, etc.
  std::string summary;
  /// Everything else pre-processing produced: PSF, sigma_n, static-source catalog, sky rate, calibration
  /// report, notes. Its `frames` and `filtered` cubes were moved into `unfiltered` and `filtered` above (the
  /// cube is held once), and its background and noise images into `layers`, so those members are empty
  /// here. Null when the pipeline did not run (test fakes).
  std::shared_ptr<const pipeline::Prepared> products;
  /// Non-empty when the cube is not held in memory (a pre-processed cube over the memory budget, opened out
  /// of core: out_of_core_controller.hpp), saying why. `filtered` then holds only a 16 x 16 corner of every
  /// frame (times, offsets, WCS, sigma_F, sky rate, PSF), not the image: what needs the whole cube (live
  /// stacks, the inspector, fits, stamp figures) says it is unavailable.
  std::string outOfCore;
};

/// A radial profile at a point of an image with its Moffat fit (paper \label{MoffatPsf}).
struct ProfileFit {
  std::vector<double> radiusPx;  ///< sample radii
  std::vector<double> value;     ///< image value at those radii
  std::vector<double> fitRadiusPx;
  std::vector<double> fitValue;  ///< fitted model on fitRadiusPx
  double fwhmPx = 0.0;
  double beta = 0.0;
  double centreX = 0.0;
  double centreY = 0.0;
  bool ok = false;
  std::string message;  ///< why the fit failed, or a short summary
};

enum class BackendKind { Auto, Cpu, Gpu };

/// One accepted step of a running co-moving fit, for the live plots (called on the fit's worker thread).
struct FitStep {
  fit::FitIteration iteration;  ///< iteration number, cost C, lambda, parameters
  /// Data - model summed along the step's track (FitResult::residualStack's layout); null when skipped
  /// (the adapter computes it at most a few times per second).
  std::shared_ptr<const Image> residual;
};

/// A finished co-moving fit of one candidate.
struct FitOutcome {
  candidate::FitSummary summary;  ///< what "Accept" stores on the candidate (candidate::fitCandidate)
  fit::FitResult result;  ///< every number: Hessian and noise-model sigmas, the paper's formulas, stacks
};
using FitStepCallback = std::function<void(const FitStep&)>;

struct CoreServices {
  /// How to hold `inputs` under a memory budget of `budgetBytes` (pipeline::planOpen: in memory, out of core
  /// for a prepared cube, refused for raw frames), called in the load job's worker before loadFrames. Empty:
  /// every input is loaded in memory (test fakes, whose inputs are not FITS files).
  std::function<pipeline::OpenPlan(const std::vector<std::string>& inputs, std::size_t budgetBytes,
                                   CancelToken& cancel)>
      planOpen;
  /// Loads files and/or folders into one cube (st::io::loadFrames).
  std::function<FrameCube(const std::vector<std::string>& inputs, ProgressSink&, CancelToken&)> loadFrames;
  /// Simulates the demo observation (st::sim preset "paper-neo").
  std::function<FrameCube(ProgressSink&, CancelToken&)> simulateDemo;
  /// The pre-processing stages with the paper's defaults.
  std::vector<StageSpec> preprocessStages;
  /// Runs pre-processing with the stages as the user set them (st::pipeline::preprocess).
  std::function<PreparedView(std::shared_ptr<const FrameCube> raw, const std::vector<StageSpec>& stages,
                             ProgressSink&, CancelToken&)>
      preprocess;
  /// Makes a fresh search backend; `message` says what was chosen and why (app/common makeBackend).
  std::function<std::unique_ptr<search::SearchBackend>(BackendKind kind, std::string& message)> makeBackend;
  /// Radial profile and Moffat fit around (x, y) of an image (st::psf).
  std::function<ProfileFit(const Image& image, double x, double y)> radialProfile;
  /// 0-based pixel -> (RA, Dec) in degrees through the cube's WCS (st::Wcs); nullopt without a WCS.
  std::function<std::optional<std::pair<double, double>>(const FrameCube& cube, double x, double y)>
      pixelToSky;
  /// Co-moving PSF fit of a candidate on the unfiltered frames with the pre-processing's PSF and sigma_n
  /// (candidate::fitCandidate); `onStep` sees every accepted iteration. Throws st::Cancelled.
  std::function<FitOutcome(const PreparedView& prepared, const search::Candidate& candidate,
                           CancelToken& cancel, const FitStepCallback& onStep)>
      fitCandidate;
  /// Names of the available GPUs, for the backend selector (empty when none).
  std::vector<std::string> gpuNames;
};

/// A service that was not provided: throws st::InputError naming it (e.g. a build without the simulator).
[[noreturn]] void throwMissingService(const char* name);

}  // namespace st::ui

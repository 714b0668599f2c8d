#include "observation_pipeline.hpp"

#include <optional>

#include "st/candidate/candidate_fit.hpp"
#include "st/report/candidate_json.hpp"
#include "load_args.hpp"
#include "st/calib/calibration.hpp"
#include "st/common/error.hpp"
#include "st/common/parallel.hpp"
#include "st/pipeline/prepared_cube.hpp"
#include "st/pipeline/preprocess.hpp"
#include "st/report/search_report.hpp"
#include "st/search/velocity_grid.hpp"

namespace st::app {

FrameCube loadCalibrationFrames(const std::vector<std::string>& files,
                                const std::optional<io::CropRegion>& crop, ProgressSink& progress,
                                CancelToken& cancel) {
  if (files.empty()) return {};
  io::LoadOptions opt;  // calibration frames need no times: a nominal clock
  opt.startMjd = 0.0;
  opt.frameRateHz = 1.0;
  opt.scienceFrames = false;  // bias/dark/flat are expected here: no 'not a science frame' warning
  opt.crop = crop;            // cropped as the science frames are, so that the masters match them
  return io::loadFrames(files, opt, progress, cancel);
}

namespace {

pipeline::Prepared prepare(const ObservationInput& in, const SearchOptions& o, ProgressSink& progress,
                           CancelToken& cancel, std::vector<std::string>& warnings) {
  FrameCube raw;
  {
    SubProgress loadProgress(progress, 0.0, 0.2);
    raw = io::loadFrames(in.inputs, in.load, loadProgress, cancel);
  }
  pipeline::checkNotPrepared(raw, "search it with --preprocessed");
  warnings = raw.warnings;
  pipeline::PreprocessParams params;
  params.calib = in.calib;
  const FrameCube bias = loadCalibrationFrames(in.bias, in.load.crop, progress, cancel);
  const FrameCube dark = loadCalibrationFrames(in.dark, in.load.crop, progress, cancel);
  const FrameCube flat = loadCalibrationFrames(in.flat, in.load.crop, progress, cancel);
  for (const FrameCube* c : {&bias, &dark, &flat})
    warnings.insert(warnings.end(), c->warnings.begin(), c->warnings.end());
  if (!bias.empty() || !dark.empty() || !flat.empty())
    params.masters = calib::buildMasters(bias, dark, flat, raw, params.calib, progress, cancel);
  SubProgress prepProgress(progress, 0.2, 0.5);
  pipeline::Prepared prepared = pipeline::preprocess(std::move(raw), params, prepProgress, cancel);
  warnings.insert(warnings.end(), prepared.calibration.warnings.begin(), prepared.calibration.warnings.end());
  if (o.fwhm) prepared.filtered.psfFwhmPx = *o.fwhm;
  if (o.sigmaF) prepared.filtered.sigmaF = *o.sigmaF;
  return prepared;
}

pipeline::PreparedSearchInput loadPrepared(const ObservationInput& in, const SearchOptions& o,
                                           ProgressSink& progress, CancelToken& cancel) {
  FrameCube frames;
  {
    SubProgress loadProgress(progress, 0.0, 0.5);
    frames = io::loadFrames(in.inputs, in.load, loadProgress, cancel);
  }
  SubProgress filterProgress(progress, 0.5, 1.0);
  return pipeline::searchInputFromPrepared(std::move(frames), {o.fwhm, o.sigmaF}, filterProgress, cancel);
}

}  // namespace

nlohmann::json runObservation(const ObservationInput& in, const SearchOptions& o, bool fit,
                              search::SearchBackend& backend, ProgressSink& progress, CancelToken& cancel,
                              const ObservationHooks& hooks) {
  if (fit && in.preprocessed)
    throw InputError(
        "the co-moving fit needs the unfiltered frames: give the raw input, not a pre-processed one");
  std::optional<pipeline::Prepared> prepared;
  std::optional<pipeline::PreparedSearchInput> loaded;
  std::vector<std::string> warnings, notes;
  if (in.preprocessed) {
    loaded = loadPrepared(in, o, progress, cancel);
    warnings = std::move(loaded->warnings);
    notes = std::move(loaded->notes);
  } else {
    prepared = prepare(in, o, progress, cancel, warnings);
  }
  const search::FilteredCube& fc = in.preprocessed ? loaded->cube : prepared->filtered;
  const search::VelocityGrid grid = search::makeVelocityGrid(o.request.grid, fc);
  const search::MethodEstimate e =
      search::estimateMethods(fc.frames.width(), fc.frames.height(), fc.frames.timeOffsetsS(), grid,
                              search::costModelFor(backend), workerCount());
  const search::MethodChoice method =
      search::chooseMethod(o.request.params.method, e, backend.supportsMethod("tree"), backend.name());
  if (hooks.planned) hooks.planned(PlannedSearch{fc, grid, e, method, warnings, notes});
  search::SearchResult r;
  if (hooks.search) {
    search::SearchParams params = o.request.params;
    params.method = method.method;
    r = hooks.search(fc, grid, params);
  } else {
    r = search::searchWithChoice(backend, fc, grid, o.request.params, method, progress, cancel);
  }
  if (hooks.searched) hooks.searched(r);
  nlohmann::json j = report::searchResultToJson(fc, r, in.inputs);
  j["t_ref_utc"] = isoFromMjd(r.tRefMjd);
  j["min_frames"] = r.minFrames;
  j["cells_above_threshold"] = r.cellsAboveThreshold;
  if (fit) {
    const double gain = prepared->frames.header.getDouble("GAIN").value_or(1.0);
    for (std::size_t i = 0; i < r.candidates.size() && static_cast<long long>(i) < o.fitMax; ++i) {
      progress.report(static_cast<double>(i) / static_cast<double>(r.candidates.size()), "co-moving fits");
      j["candidates"][i]["fit"] =
          report::toFlatJson(candidate::fitCandidate(*prepared, r.candidates[i], gain, cancel));
    }
  }
  return j;
}

}  // namespace st::app

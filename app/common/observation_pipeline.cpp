#include "observation_pipeline.hpp"

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <optional>

#include "backend_factory.hpp"
#include "st/candidate/candidate_fit.hpp"
#include "st/report/candidate_json.hpp"
#include "load_args.hpp"
#include "st/calib/calibration.hpp"
#include "st/common/error.hpp"
#include "st/common/parallel.hpp"
#include "st/pipeline/memory_plan.hpp"
#include "st/pipeline/plate_solve_stage.hpp"
#include "st/pipeline/prepared_cube.hpp"
#include "st/pipeline/raw_out_of_core.hpp"
#include "st/search/tiled_search.hpp"
#include "st/stack/matched_filter.hpp"
#include "st/pipeline/preprocess.hpp"
#include "st/report/search_report.hpp"
#include "st/search/default_grid.hpp"
#include "st/search/velocity_grid.hpp"

namespace st::app {

pipeline::Prepared prepareObservation(const ObservationInput& in, const SearchOptions& o,
                                      ProgressSink& progress, CancelToken& cancel,
                                      std::vector<std::string>& warnings, bool keepZeroBiased,
                                      const std::function<pipeline::PreprocessAccelerator*()>& accelerator) {
  FrameCube raw;
  const auto loadStart = std::chrono::steady_clock::now();
  {
    SubProgress loadProgress(progress, 0.0, 0.2);
    raw = io::loadFrames(in.inputs, in.load, loadProgress, cancel);
  }
  const double loadSeconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - loadStart).count();
  pipeline::checkNotPrepared(raw, "search it with --preprocessed");
  warnings = raw.warnings;
  // The device (made while the frames were read) is asked for now, before plate solving and the calibration
  // frames: a backend that cannot be had stops the job before that work, not after it.
  pipeline::PreprocessAccelerator* const device = accelerator ? accelerator() : nullptr;
  // --plate-solve (pipeline/plate_solve_stage.hpp): the first raw frame, else the star catalogue after
  // pre-processing; a search without a WCS is still a search, so a failure is a warning.
  std::string solved;
  bool solveCatalogue = false;
  if (o.plateSolve && !raw.wcs) {
    try {
      SubProgress solveProgress(progress, 0.2, 0.2);
      solved = "WCS of the first frame " + pipeline::describeSolution(pipeline::plateSolveRawCube(
                                               raw, o.plateSolveParams, solveProgress, cancel));
    } catch (const InputError& e) {
      solveCatalogue = true;
      solved = std::string("plate solving the first frame: ") + e.what();
    }
  }
  pipeline::PreprocessParams params;
  params.accelerator = device;
  params.calib = in.calib;
  params.keepZeroBiased = keepZeroBiased;
  params.registerFrames = o.registerFrames;
  const FrameCube bias = loadCalibrationFrames(in.bias, in.load.crop, progress, cancel);
  const FrameCube dark = loadCalibrationFrames(in.dark, in.load.crop, progress, cancel);
  const FrameCube flat = loadCalibrationFrames(in.flat, in.load.crop, progress, cancel);
  for (const FrameCube* c : {&bias, &dark, &flat})
    warnings.insert(warnings.end(), c->warnings.begin(), c->warnings.end());
  if (!bias.empty() || !dark.empty() || !flat.empty())
    params.masters = calib::buildMasters(bias, dark, flat, raw, params.calib, progress, cancel);
  SubProgress prepProgress(progress, 0.2, 0.5);
  pipeline::Prepared prepared = pipeline::preprocess(std::move(raw), params, prepProgress, cancel);
  prepared.stageSeconds.insert(prepared.stageSeconds.begin(), {"read the frames", loadSeconds});
  warnings.insert(warnings.end(), prepared.calibration.warnings.begin(), prepared.calibration.warnings.end());
  if (!solved.empty()) prepared.notes.push_back(solved);
  if (solveCatalogue) {
    try {
      SubProgress solveProgress(progress, 0.5, 0.5);
      pipeline::plateSolvePrepared(prepared, o.plateSolveParams, solveProgress, cancel);
    } catch (const InputError& e) {
      warnings.push_back(std::string("no WCS: plate solving the star catalogue: ") + e.what());
    }
  }
  if (o.fwhm) prepared.filtered.psfFwhmPx = *o.fwhm;
  if (o.sigmaF) prepared.filtered.sigmaF = *o.sigmaF;
  return prepared;
}

namespace {

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

namespace {

constexpr search::SearchMethod kExact = search::SearchMethod::Exact;
constexpr search::SearchMethod kTree = search::SearchMethod::Tree;
constexpr search::SearchMethod kAuto = search::SearchMethod::Auto;

/// The image's offset in the files (the user's --crop).
std::pair<int, int> cropOrigin(const ObservationInput& in) {
  return in.load.crop ? std::pair{in.load.crop->x0, in.load.crop->y0} : std::pair{0, 0};
}

/// Frames of `r` (image coordinates) of the input, read with CFITSIO's subset reader.
FrameCube loadRegion(const ObservationInput& in, const search::TileRect& r, CancelToken& cancel) {
  io::LoadOptions lo = in.load;
  const auto [bx, by] = cropOrigin(in);
  lo.crop = io::CropRegion{bx + r.x0, by + r.y0, r.width, r.height};
  NullProgress quiet;
  return io::loadFrames(in.inputs, lo, quiet, cancel);
}

/// A pre-processed input too large for memory: its header, times and WCS from a small corner (the WCS of
/// a corner at the image's origin is the image's), sigma_F from the header or the options, else measured on
/// a central region of `sigmaRegionPx` x `sigmaRegionPx` px.
struct OutOfCoreInput {
  search::FilteredCube meta;
  pipeline::PreparedHeader header;
  std::vector<std::string> warnings, notes;
};

OutOfCoreInput outOfCoreMeta(const ObservationInput& in, const SearchOptions& o, int width, int height,
                             CancelToken& cancel) {
  OutOfCoreInput m;
  FrameCube corner = loadRegion(in, {0, 0, std::min(width, 16), std::min(height, 16)}, cancel);
  const std::string source = pipeline::cubeSource(corner);
  m.header = pipeline::readPreparedHeader(corner.header, source);
  m.warnings = corner.warnings;
  m.meta.skyRate = m.header.skyRate;
  const std::optional<psf::Moffat> psf = m.header.psf;
  if (o.fwhm) {
    m.meta.psfFwhmPx = *o.fwhm;
  } else if (psf) {
    m.meta.psfFwhmPx = psf->fwhm();
  } else {
    throw InputError(source + ": no PSFFWHM in the header: give --fwhm");
  }
  if (o.sigmaF) {
    m.meta.sigmaF = *o.sigmaF;
  } else if (m.header.state == pipeline::PreparedState::Filtered && m.header.sigmaF) {
    m.meta.sigmaF = *m.header.sigmaF;
  }
  m.meta.frames = std::move(corner);
  return m;
}

/// sigma_F of an out-of-core zero-biased (or SIGMAF-less) cube: filtered and measured on the central region.
double centralSigmaF(const ObservationInput& in, const SearchOptions& o, int width, int height, int side,
                     std::vector<std::string>& notes, CancelToken& cancel) {
  const int w = std::min(width, side), h = std::min(height, side);
  const search::TileRect r{(width - w) / 2, (height - h) / 2, w, h};
  NullProgress quiet;
  pipeline::PreparedSearchInput p =
      pipeline::searchInputFromPrepared(loadRegion(in, r, cancel), {o.fwhm, std::nullopt}, quiet, cancel);
  notes.push_back("out of core: sigma_F " + std::to_string(p.cube.sigmaF) + " measured on the central " +
                  std::to_string(w) + " x " + std::to_string(h) +
                  " px (give --sigma-f, or a filtered cube with SIGMAF, for the in-memory value)");
  return p.cube.sigmaF;
}

nlohmann::json resultJson(const search::FilteredCube& fc, const search::SearchResult& r,
                          const ObservationInput& in) {
  nlohmann::json j = report::searchResultToJson(fc, r, in.inputs);
  j["t_ref_utc"] = isoFromMjd(r.tRefMjd);
  j["min_frames"] = r.minFrames;
  j["cells_above_threshold"] = r.cellsAboveThreshold;
  return j;
}

}  // namespace

namespace {

// The search's grid: the options' (+-12 deg/day by default), or with --grid-auto the data-derived default of
// search/default_grid.hpp for this cube and backend (a note says which bound set it).
search::VelocityGrid observationGrid(const SearchOptions& o, const search::FilteredCube& fc,
                                     const search::SearchBackend& backend, int width, int height,
                                     std::vector<std::string>& notes) {
  if (!o.autoGrid) return search::makeVelocityGrid(o.request.grid, fc);
  search::DefaultGridInput in;
  in.width = width;
  in.height = height;
  in.frames = fc.frames.frameCount();
  in.timeSpanS = fc.frames.timeSpanS();
  in.plateScaleArcsecPerPx = fc.frames.plateScaleArcsecPerPx;
  in.centre = o.request.grid.centre.value_or(fc.skyRate);
  in.model = search::costModelFor(backend);
  in.minFrameFraction = o.request.params.minFrameFraction;
  in.stepPx = o.request.grid.stepPx;
  const search::DefaultGrid d = search::defaultVelocityGrid(in);
  notes.push_back("grid (--grid-auto): " + search::describeDefaultGrid(d, in.plateScaleArcsecPerPx));
  return d.grid;
}

}  // namespace

nlohmann::json runObservation(const ObservationInput& in, const SearchOptions& options, bool fit,
                              search::SearchBackend& backend, ProgressSink& progress, CancelToken& cancel,
                              const ObservationHooks& hooks) {
  return runObservation(
      in, options, fit, [&backend]() -> search::SearchBackend& { return backend; }, progress, cancel, hooks);
}

nlohmann::json runObservation(const ObservationInput& in, const SearchOptions& optionsIn, bool fit,
                              const std::function<search::SearchBackend&()>& backendSource,
                              ProgressSink& progress, CancelToken& cancel, const ObservationHooks& hooks) {
  if (fit && in.preprocessed)
    throw InputError(
        "the co-moving fit needs the unfiltered frames: give the raw input, not a pre-processed one");
  SearchOptions o = optionsIn;
  MemoryPlan memory;
  memory.budget = resolveMemoryBudget(o.memoryLimit);
  o.request.params.bufferBytes = pipeline::searchBufferBytes(memory.budget.bytes);
  const unsigned threads = workerCount();
  const io::InputSummary summary = io::summarizeInputs(in.inputs, in.load);
  const pipeline::CubeShape shape{summary.width, summary.height, summary.frames};
  const double budget = static_cast<double>(memory.budget.bytes);
  memory.lines.push_back("memory budget " + formatBytes(budget) + " (" + memory.budget.source + ")");

  std::optional<pipeline::Prepared> prepared;
  std::optional<pipeline::PreparedSearchInput> loaded;
  std::optional<OutOfCoreInput> ooc;
  std::vector<std::string> warnings, notes;
  // Raw frames pre-processed out of core: their filtered cube on disk is then searched as a pre-processed
  // input (`src`), and removed afterwards unless --keep-scratch.
  std::optional<pipeline::OutOfCorePrepared> prepOoc;
  ObservationInput scratchInput;
  const ObservationInput* src = &in;
  struct ScratchGuard {
    std::string path;
    ~ScratchGuard() {
      std::error_code ec;
      if (!path.empty()) std::filesystem::remove(path, ec);
    }
  } scratchGuard;
  if (!in.preprocessed) {
    // Raw frames are pre-processed in memory when the whole cube fits (the search is counted below), else
    // out of core in strips of rows.
    memory.inMemory = pipeline::estimatePreprocessPeak(shape, fit, threads);
    const bool fits = memory.inMemory.total() <= budget;
    memory.lines.push_back("pre-processing in memory: estimated peak " + memory.inMemory.describe() +
                           (fits ? "" : ": over the budget"));
    if (!fits && fit) {
      throw InputError(pipeline::overBudgetMessage(
          std::to_string(shape.frames) + " frames of " + std::to_string(shape.width) + " x " +
              std::to_string(shape.height) +
              " px: pre-processing in memory (--fit needs the whole zero-biased cube; without --fit the "
              "frames are pre-processed out of core)",
          memory.inMemory, memory.budget));
    }
    if (fits) {
      if (hooks.memory) hooks.memory(memory);
      // The pre-processing on the search's GPU, if any; the backend is waited for after the frames are read.
      std::unique_ptr<pipeline::PreprocessAccelerator> accel;
      prepared = prepareObservation(in, o, progress, cancel, warnings, fit, [&] {
        std::string accelMessage;
        accel = makePreprocessAccelerator(backendSource(), accelMessage);
        return accel.get();
      });
      if (hooks.prepared) hooks.prepared(*prepared);
    } else {
      // Out of core in strips of rows (pipeline/raw_out_of_core.hpp): planned (and shown) before any pixel.
      // The backend first: one that cannot be had (--backend cuda without a device) stops the job before the
      // strips are pre-processed, not after.
      (void)backendSource();
      const pipeline::RawObservationFiles files{in.inputs, in.load, in.bias, in.dark, in.flat, in.calib};
      const pipeline::RawOutOfCorePlan plan = pipeline::planRawOutOfCore(
          files, summary, {o.registerFrames, o.scratchDir, o.keepScratch}, memory.budget, threads);
      memory.lines.push_back(plan.description);
      if (hooks.memory) hooks.memory(memory);
      SubProgress sub(progress, 0.0, 0.5);
      prepOoc = pipeline::preprocessRawOutOfCore(files, summary, plan, sub, cancel);
      if (!o.keepScratch) scratchGuard.path = prepOoc->path;
      scratchInput.inputs = {prepOoc->path};
      scratchInput.preprocessed = true;
      src = &scratchInput;
    }
  }
  if (!prepared) {
    // A pre-processed cube: searched in memory when cube + search fit, else in tiles.
    search::SearchBackend& backend = backendSource();
    OutOfCoreInput m = outOfCoreMeta(*src, o, shape.width, shape.height, cancel);
    std::vector<std::string> unused;
    const search::VelocityGrid grid0 = observationGrid(o, m.meta, backend, shape.width, shape.height, unused);
    const search::MethodEstimate e0 = search::estimateMethods(
        shape.width, shape.height, m.meta.frames.timeOffsetsS(), grid0, search::costModelFor(backend),
        threads, o.request.params.bufferBytes, m.meta.frames.frameOffsets());
    const search::MethodChoice c0 =
        search::chooseMethod(o.request.params.method, e0, backend.supports(kTree), backend.name());
    memory.inMemory = pipeline::estimateSearchPeak(shape, e0, c0.method);
    const bool fits = memory.inMemory.total() <= budget;
    memory.lines.push_back("search in memory: estimated peak " + memory.inMemory.describe() +
                           (fits ? "" : ": over the budget, out of core"));
    if (hooks.memory) hooks.memory(memory);
    if (fits) {
      loaded = loadPrepared(*src, o, progress, cancel);
      warnings = std::move(loaded->warnings);
      notes.insert(notes.end(), loaded->notes.begin(), loaded->notes.end());
    } else {
      ooc = std::move(m);
      warnings = ooc->warnings;
    }
  }
  if (prepOoc) {
    warnings.insert(warnings.begin(), prepOoc->warnings.begin(), prepOoc->warnings.end());
    notes.insert(notes.begin(), prepOoc->notes.begin(), prepOoc->notes.end());
    if (o.plateSolve)
      warnings.push_back("--plate-solve is not done out of core: the frames' own WCS is used");
  }
  search::FilteredCube* fcp = nullptr;
  if (prepared) fcp = &prepared->filtered;
  if (loaded) fcp = &loaded->cube;
  if (ooc) fcp = &ooc->meta;
  search::FilteredCube& fc = *fcp;
  const int width = shape.width, height = shape.height;
  search::SearchBackend& backend = backendSource();
  const search::VelocityGrid grid = observationGrid(o, fc, backend, width, height, notes);
  // Out of core the tiles are searched on the CPU (tiled_search.hpp), whatever the backend: priced so.
  const search::MethodCostModel model = ooc ? search::cpuCostModel(threads) : search::costModelFor(backend);
  search::MethodEstimate e =
      search::estimateMethods(width, height, fc.frames.timeOffsetsS(), grid, model, threads,
                              o.request.params.bufferBytes, fc.frames.frameOffsets());
  search::setPsf(e, fc.psfFwhmPx);  // auto's SNR rule for the tree (issue 16)
  search::MethodChoice method =
      search::chooseMethod(o.request.params.method, e, backend.supports(kTree), backend.name());
  std::vector<search::SearchTile> tiles;
  unsigned treeThreads = 0;  // out of core: the tree's threads that fit the budget
  if (ooc) {
    memory.outOfCore = true;
    // The search's overlap, plus the matched filter's reach when tiles are filtered on loading.
    int overlap = search::searchOverlapPx(grid, fc.frames.timeOffsetsS());
    const bool filterTiles = ooc->header.state == pipeline::PreparedState::ZeroBiased;
    if (filterTiles) {
      const psf::Moffat psf =
          o.fwhm ? psf::Moffat::fromFwhm(*o.fwhm,
                                         ooc->header.psf ? ooc->header.psf->beta : pipeline::kDefaultPsfBeta)
                 : *ooc->header.psf;
      overlap += stack::makeFilterKernel(psf).halfSize;
    }
    pipeline::TiledSearchPlan plan = pipeline::planTiledSearch(shape, overlap, memory.budget.bytes, e,
                                                               std::string(method.method.name()), threads);
    if (plan.tiles.empty() && method.method == kTree && o.request.params.method == kAuto) {
      // The tree's partial stacks do not fit beside a tile: the exact kernel's scratch is small.
      plan = pipeline::planTiledSearch(shape, overlap, memory.budget.bytes, e, "exact", threads);
      if (!plan.tiles.empty())
        method = {kExact,
                  "auto: exact (the tree search's buffers do not fit the memory budget beside a tile)"};
    }
    if (plan.tiles.empty()) {
      throw InputError(pipeline::overBudgetMessage(
          "searching " + std::to_string(shape.frames) + " frames out of core (the smallest tile, " +
              std::to_string(8 + 2 * overlap) + " x " + std::to_string(8 + 2 * overlap) +
              " px with the overlap of the largest shift)",
          plan.smallestTile, memory.budget));
    }
    tiles = plan.tiles;
    treeThreads = plan.treeThreads;
    memory.tiles = tiles.size();
    memory.overlapPx = overlap;
    memory.perTile = plan.perTile;
    if (!(fc.sigmaF > 0.0)) {
      const int side =
          std::max(64, static_cast<int>(std::sqrt(static_cast<double>(tiles.front().read.pixels()))));
      fc.sigmaF = centralSigmaF(*src, o, width, height, std::min(side, 1024), ooc->notes, cancel);
    }
    notes.insert(notes.end(), ooc->notes.begin(), ooc->notes.end());
    memory.lines.push_back("out of core: " + std::to_string(tiles.size()) + " tiles (overlap " +
                           std::to_string(overlap) + " px), estimated peak " + memory.perTile.describe());
  } else {
    const pipeline::CubeShape held{width, height, fc.frames.frameCount()};
    if (prepared) {
      const auto peakOf = [&](search::SearchMethod m) {
        MemoryEstimate p = pipeline::estimateSearchPeak(held, e, m);
        p.add("per-pixel images", pipeline::kPreprocessImageBytesPerPixel * width * height);
        if (fit) p.add("zero-biased cube (for --fit)", 4.0 * held.samples());
        return p;
      };
      MemoryEstimate searchPeak = peakOf(method.method);
      if (searchPeak.total() > budget && method.method == kTree && o.request.params.method == kAuto &&
          peakOf(kExact).total() <= budget) {
        method = {kExact, "auto: exact (the tree search's buffers do not fit the memory budget)"};
        searchPeak = peakOf(kExact);
      }
      memory.lines.push_back("search in memory: estimated peak " + searchPeak.describe() +
                             (searchPeak.total() > budget ? " (over the budget)" : ""));
    }
  }
  if (hooks.planned)
    hooks.planned(PlannedSearch{fc, grid, e, method, warnings, notes, width, height, memory});
  search::SearchResult r;
  if (ooc) {
    search::SearchParams params = o.request.params;
    params.method = method.method;
    params.treeThreads = treeThreads;
    const search::FilteredCube& meta = fc;
    const bool filterTiles = ooc->header.state == pipeline::PreparedState::ZeroBiased;
    const search::TileLoader load = [&](const search::TileRect& t) {
      NullProgress quiet;
      pipeline::PreparedSearchInput p = pipeline::searchInputFromPrepared(
          loadRegion(*src, t, cancel), {o.fwhm, meta.sigmaF}, quiet, cancel);
      (void)filterTiles;
      return std::move(p.cube);
    };
    // The tree's candidates re-scored by the exact statistic after it (as searchWithChoice does in memory):
    // the tiles that own them read again, the last tenth of the progress.
    const bool tree = params.method == search::SearchMethod::Tree;
    SubProgress searching(progress, 0.0, tree ? 0.9 : 1.0), rescoring(progress, 0.9, 1.0);
    r = search::searchTiled(load, tiles, width, height, grid, params, searching, cancel);
    r.methodReason = method.reason;
    r.backendNote += ", " + std::to_string(memory.overlapPx) + " px overlap";
    if (tree) (void)search::polishTiledTreeCandidates(load, tiles, r, rescoring, cancel);
    if (backend.name().rfind("cpu", 0) != 0) r.warnings.push_back("out of core: the search ran on the CPU");
  } else if (hooks.search) {
    search::SearchParams params = o.request.params;
    params.method = method.method;
    r = hooks.search(fc, grid, params);
  } else {
    r = search::searchWithChoice(backend, fc, grid, o.request.params, method, progress, cancel);
  }
  if (hooks.searched) hooks.searched(r);
  nlohmann::json j = resultJson(fc, r, in);
  j["memory"] = {{"budget_bytes", memory.budget.bytes},
                 {"budget_source", memory.budget.source},
                 {"in_memory_estimate_bytes", memory.inMemory.total()},
                 {"out_of_core", memory.outOfCore},
                 {"tiles", memory.tiles},
                 {"peak_resident_bytes", peakResidentBytes()}};
  if (fit) {
    for (std::size_t i = 0; i < r.candidates.size() && static_cast<long long>(i) < o.fitMax; ++i) {
      progress.report(static_cast<double>(i) / static_cast<double>(r.candidates.size()), "co-moving fits");
      j["candidates"][i]["fit"] =
          report::toFlatJson(candidate::fitCandidate(*prepared, r.candidates[i], cancel));
    }
  }
  return j;
}

}  // namespace st::app

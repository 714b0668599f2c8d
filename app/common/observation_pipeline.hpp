#pragma once
// One observation through the whole pipeline, as `synthtrack-cli search [--fit]` runs it: load, pre-process
// (or take a pre-processed cube), velocity grid, method choice, search, co-moving fits, the result JSON.
// `search` and every observation of `batch` call this one function, so a batch gives what separate
// searches give.
#include <functional>
#include <string>
#include <vector>

#include "st/calib/calibration.hpp"
#include "st/common/memory_budget.hpp"

#include <nlohmann/json.hpp>

#include "search_options.hpp"
#include "st/common/progress.hpp"
#include "st/io/fits_reader.hpp"
#include "st/pipeline/preprocess.hpp"
#include "st/pipeline/raw_out_of_core.hpp"
#include "st/search/method_choice.hpp"
#include "st/search/types.hpp"

namespace st::app {

struct ObservationInput {
  std::vector<std::string> inputs;  ///< files or folders, one observation
  io::LoadOptions load;
  bool preprocessed = false;                  ///< INPUT was written by `preprocess` (no --fit then)
  std::vector<std::string> bias, dark, flat;  ///< calibration frames for the pre-processing
  calib::CalibParams calib;  ///< overscan / section choices (--no-overscan, --ignore-sections)
};

/// Loads bias, dark or flat frames (pipeline/raw_out_of_core.hpp).
using pipeline::loadCalibrationFrames;

/// The memory plan of the run (issue 20), printed with the search plan.
struct MemoryPlan {
  MemoryBudget budget;
  MemoryEstimate inMemory;           ///< the in-memory path's peak
  bool outOfCore = false;            ///< searched in tiles (the in-memory path does not fit)
  std::size_t tiles = 0;             ///< tiles of the out-of-core search
  int overlapPx = 0;                 ///< their overlap
  MemoryEstimate perTile;            ///< the out-of-core peak
  std::vector<std::string> lines;    ///< the plan in words, for the log
};

/// What is known just before the search: for printing the plan.
struct PlannedSearch {
  const search::FilteredCube& cube;  ///< out of core: a small corner of the frames (times, header, WCS)
  const search::VelocityGrid& grid;
  const search::MethodEstimate& estimate;
  const search::MethodChoice& choice;
  const std::vector<std::string>& warnings;  ///< the loader's
  const std::vector<std::string>& notes;     ///< pre-processing's
  int width = 0;                             ///< the whole image's
  int height = 0;
  const MemoryPlan& memory;
};

struct ObservationHooks {
  /// The memory budget and the estimate of the first stage, before any pixel is read (MemoryPlan::lines so
  /// far); planned() gets the lines added after it.
  std::function<void(const MemoryPlan&)> memory;
  /// After loading and pre-processing in memory (its stageSeconds begin with "read the frames").
  std::function<void(const pipeline::Prepared&)> prepared;
  std::function<void(const PlannedSearch&)> planned;          ///< before the search
  std::function<void(const search::SearchResult&)> searched;  ///< after it, before the fits
  /// Replaces backend.search (search --mpi: the grid split over ranks). Gets the grid and the parameters
  /// with the method resolved.
  std::function<search::SearchResult(const search::FilteredCube&, const search::VelocityGrid&,
                                     const search::SearchParams&)>
      search;
};

/// Loads and pre-processes a raw observation as runObservation does (the loader's and calibration's
/// warnings in `warnings`); --fwhm / --sigma-f of `options` applied. Used by batch to re-measure a track
/// over several cubes. Without keepZeroBiased the matched filter runs in place (no zero-biased frames kept,
/// so no co-moving fit afterwards). `accelerator`, when given, is asked once, right after the raw frames are
/// read (before plate solving and the calibration frames), for the device that pre-processes (null: the CPU).
pipeline::Prepared prepareObservation(const ObservationInput& input, const SearchOptions& options,
                                      ProgressSink& progress, CancelToken& cancel,
                                      std::vector<std::string>& warnings, bool keepZeroBiased = true,
                                      const std::function<pipeline::PreprocessAccelerator*()>& accelerator = {});

/// Runs the observation and returns the result JSON. Memory (issue 20): the budget is options.memoryLimit
/// or the default; raw input whose in-memory pre-processing does not fit is pre-processed out of core in
/// strips of rows into a filtered cube in options.scratchDir (pipeline/preprocess_out_of_core.hpp), which is
/// then searched as a pre-processed cube and removed unless options.keepScratch; with `fit`, or when not
/// even one strip fits, it stops with st::InputError before any pixel is read (naming the need and the
/// budget); a pre-processed cube whose in-memory search does not
/// fit is searched out of core (search/tiled_search.hpp), or stops so when not even one tile fits. Without
/// `fit` the matched filter runs in place (no zero-biased copy).
/// Returns the result JSON (report::searchResultToJson plus t_ref_utc, and with
/// `fit` a "fit" object for each of the first options.fitMax candidates). Throws what loading,
/// pre-processing and the search throw (st::InputError, st::FitsError, st::Cancelled), and st::InputError
/// when `fit` is asked of a pre-processed input.
nlohmann::json runObservation(const ObservationInput& input, const SearchOptions& options, bool fit,
                              search::SearchBackend& backend, ProgressSink& progress, CancelToken& cancel,
                              const ObservationHooks& hooks = {});

/// The same with the backend asked of `backend` where first needed: right after raw frames held in memory are
/// read (a backend made on another thread meanwhile, BackendInTheMaking, costs the read nothing); on every
/// other path before any pixel is processed.
nlohmann::json runObservation(const ObservationInput& input, const SearchOptions& options, bool fit,
                              const std::function<search::SearchBackend&()>& backend, ProgressSink& progress,
                              CancelToken& cancel, const ObservationHooks& hooks = {});

}  // namespace st::app

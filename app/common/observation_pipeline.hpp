#pragma once
// One observation through the whole pipeline, as `synthtrack-cli search [--fit]` runs it: load, pre-process
// (or take a pre-processed cube), velocity grid, method choice, search, co-moving fits, the result JSON.
// `search` and every observation of `batch` call this one function, so a batch gives what separate
// searches give.
#include <functional>
#include <string>
#include <vector>

#include "st/calib/calibration.hpp"

#include <nlohmann/json.hpp>

#include "search_options.hpp"
#include "st/common/progress.hpp"
#include "st/io/fits_reader.hpp"
#include "st/pipeline/preprocess.hpp"
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

/// Loads bias, dark or flat frames (files or folders; none = an empty cube) with a nominal clock, no
/// science-frame warnings, cropped with `crop` as the science frames are.
FrameCube loadCalibrationFrames(const std::vector<std::string>& files,
                                const std::optional<io::CropRegion>& crop, ProgressSink& progress,
                                CancelToken& cancel);

/// What is known just before the search: for printing the plan.
struct PlannedSearch {
  const search::FilteredCube& cube;
  const search::VelocityGrid& grid;
  const search::MethodEstimate& estimate;
  const search::MethodChoice& choice;
  const std::vector<std::string>& warnings;  ///< the loader's
  const std::vector<std::string>& notes;     ///< pre-processing's
};

struct ObservationHooks {
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
/// over several cubes.
pipeline::Prepared prepareObservation(const ObservationInput& input, const SearchOptions& options,
                                      ProgressSink& progress, CancelToken& cancel,
                                      std::vector<std::string>& warnings);

/// Runs the observation and returns the result JSON (report::searchResultToJson plus t_ref_utc, and with
/// `fit` a "fit" object for each of the first options.fitMax candidates). Throws what loading,
/// pre-processing and the search throw (st::InputError, st::FitsError, st::Cancelled), and st::InputError
/// when `fit` is asked of a pre-processed input.
nlohmann::json runObservation(const ObservationInput& input, const SearchOptions& options, bool fit,
                              search::SearchBackend& backend, ProgressSink& progress, CancelToken& cancel,
                              const ObservationHooks& hooks = {});

}  // namespace st::app

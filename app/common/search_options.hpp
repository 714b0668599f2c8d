#pragma once
// The search options shared by `synthtrack-cli search` and `batch` (and a batch manifest's per-observation
// "params"): one parser, so an observation in a batch is searched exactly as `search` would search it.
#include <optional>
#include <set>
#include <string>

#include "cli_args.hpp"
#include "st/astro/plate_solve.hpp"
#include "st/search/search_run.hpp"

namespace st::app {

struct SearchOptions {
  search::SearchRequest request;
  std::optional<double> sigmaF;  ///< override of the filtered frames' noise
  std::optional<double> fwhm;    ///< override of the PSF FWHM (px)
  bool registerFrames = true;    ///< per-frame registration in pre-processing (--no-register turns it off)
  /// --grid-auto: the GUI's data-derived default grid (search/default_grid.hpp: at most +-12 deg/day, what
  /// stays in the frame, and about a minute of exact search on this backend) instead of +-12 deg/day.
  bool autoGrid = false;
  /// --plate-solve: raw frames without a WCS get one from astrometry.net before pre-processing
  /// (pipeline::plateSolveRawCube), with these settings (plate_solve_args.hpp).
  bool plateSolve = false;
  astro::PlateSolveParams plateSolveParams;
  std::string backend = "auto";
  /// --frame-precision: "fp32" (default) or "fp16" (CUDA exact search only; backend_factory.hpp)
  std::string framePrecision = "fp32";
  long long fitMax = 50;  ///< candidates refined by the co-moving fit (--fit-max)
  /// --memory-limit ("8G", "500M"); none = the default budget (st/common/memory_budget.hpp)
  std::optional<std::string> memoryLimit;
  /// --scratch DIR: where raw frames pre-processed out of core write their filtered cube (default: the
  /// current directory); --keep-scratch keeps it (a cube to search again with --preprocessed).
  std::string scratchDir = ".";
  bool keepScratch = false;
};

/// Names of the valued options parseSearchOptions reads (without "--").
std::set<std::string> searchOptionNames();

/// Names of the valueless options (flags) parseSearchOptions reads: grid-step-fwhm, no-register, plate-solve
/// and plate_solve_args.hpp's.
std::set<std::string> searchFlagNames();

/// Help text for those options (one per line, indented).
const char* searchOptionsHelp();

/// SearchOptions from parsed arguments (defaults: +-12 deg/day, step 1 px over the span, SNR 7, method auto,
/// backend auto, fit-max 50). Throws UsageError naming the option at fault.
SearchOptions parseSearchOptions(const CliArgs& cli);

}  // namespace st::app

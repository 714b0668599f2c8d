#pragma once
// Options shared by the commands that plate-solve (solve, preprocess --plate-solve): hints and limits for
// astrometry.net's solve-field (st/astro/plate_solve.hpp).
#include <set>
#include <string>

#include "cli_args.hpp"
#include "st/astro/plate_solve.hpp"

namespace st::app {

/// Names of the valued options parsed by plateSolveParamsFromArgs.
std::set<std::string> plateSolveOptionNames();
/// Names of its flags.
std::set<std::string> plateSolveFlagNames();
/// Help text for those options (one per line, indented).
const char* plateSolveOptionsHelp();
/// PlateSolveParams from parsed arguments. Throws UsageError for values out of range.
astro::PlateSolveParams plateSolveParamsFromArgs(const CliArgs& args);

}  // namespace st::app

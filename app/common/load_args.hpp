#pragma once
// Options shared by the commands that load frames (info, convert): --hdu, --start-mjd, --frame-rate,
// --exposure, --crop, --plate-scale; and by those that calibrate them (preprocess, search): --no-overscan,
// --ignore-sections.
#include <set>
#include <string>

#include "cli_args.hpp"
#include "st/calib/calibration.hpp"
#include "st/io/fits_reader.hpp"

namespace st::app {

/// Names of the valued options parsed by loadOptionsFromArgs.
std::set<std::string> loadOptionNames();
/// Help text for those options (one per line, indented).
const char* loadOptionsHelp();
/// LoadOptions from parsed arguments. Throws UsageError for malformed values (--crop needs [x1:x2,y1:y2]).
io::LoadOptions loadOptionsFromArgs(const CliArgs& args);
/// Names of the calibration flags parsed by calibParamsFromArgs.
std::set<std::string> calibFlagNames();
/// Help text for those flags.
const char* calibOptionsHelp();
/// Calibration settings from parsed arguments: --no-overscan (no BIASSEC subtraction), --ignore-sections
/// (no BIASSEC, TRIMSEC or DATASEC from the headers).
calib::CalibParams calibParamsFromArgs(const CliArgs& args);
/// Prints each warning to stderr as "warning: ..."; when one is about an image section, adds once how to
/// overrule the headers.
void printWarnings(const std::vector<std::string>& warnings);

/// "YYYY-MM-DDThh:mm:ss.sss" for an MJD (UTC).
std::string isoFromMjd(double mjd);

}  // namespace st::app

#pragma once
// Options shared by the commands that load frames (info, convert): --hdu, --start-mjd, --frame-rate,
// --exposure, --crop, --plate-scale.
#include <set>
#include <string>

#include "cli_args.hpp"
#include "st/io/fits_reader.hpp"

namespace st::app {

/// Names of the valued options parsed by loadOptionsFromArgs.
std::set<std::string> loadOptionNames();
/// Help text for those options (one per line, indented).
const char* loadOptionsHelp();
/// LoadOptions from parsed arguments. Throws UsageError for malformed values (--crop needs [x1:x2,y1:y2]).
io::LoadOptions loadOptionsFromArgs(const CliArgs& args);
/// "YYYY-MM-DDThh:mm:ss.sss" for an MJD (UTC).
std::string isoFromMjd(double mjd);

}  // namespace st::app

#include "cli_args.hpp"
#include "commands.hpp"

namespace st::app {

int cmdPreprocess(const Args&) { throw UsageError("'preprocess' is not implemented yet"); }

}  // namespace st::app

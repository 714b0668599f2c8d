#include "cli_args.hpp"
#include "commands.hpp"

namespace st::app {

int benchPreprocess(const Args&) { throw UsageError("benchmark 'preprocess' is not implemented yet"); }

}  // namespace st::app

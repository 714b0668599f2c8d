#include "cli_args.hpp"
#include "commands.hpp"

namespace st::app {

int cmdSearch(const Args&) { throw UsageError("'search' is not implemented yet"); }

}  // namespace st::app

#include "cli_args.hpp"
#include "commands.hpp"

namespace st::app {

int benchSearch(const Args&) { throw UsageError("benchmark 'search' is not implemented yet"); }

}  // namespace st::app

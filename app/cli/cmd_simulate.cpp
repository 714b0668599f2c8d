#include "cli_args.hpp"
#include "commands.hpp"

namespace st::app {

int cmdSimulate(const Args&) { throw UsageError("'simulate' is not implemented yet"); }

}  // namespace st::app

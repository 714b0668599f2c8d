#include "cli_args.hpp"
#include "commands.hpp"

namespace st::app {

int cmdFit(const Args&) { throw UsageError("'fit' is not implemented yet"); }

}  // namespace st::app

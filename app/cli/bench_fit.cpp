#include "cli_args.hpp"
#include "commands.hpp"

namespace st::app {

int benchFit(const Args&) { throw UsageError("benchmark 'fit' is not implemented yet"); }

}  // namespace st::app

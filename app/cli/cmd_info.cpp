#include "cli_args.hpp"
#include "commands.hpp"

namespace st::app {

int cmdInfo(const Args&) { throw UsageError("'info' is not implemented yet"); }

}  // namespace st::app

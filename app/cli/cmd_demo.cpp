#include "cli_args.hpp"
#include "commands.hpp"

namespace st::app {

int cmdDemo(const Args&) { throw UsageError("'demo' is not implemented yet"); }

}  // namespace st::app

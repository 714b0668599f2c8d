#include "cli_args.hpp"
#include "commands.hpp"

namespace st::app {

int cmdStack(const Args&) { throw UsageError("'stack' is not implemented yet"); }

}  // namespace st::app

#include "cli_args.hpp"
#include "commands.hpp"

namespace st::app {

int benchStack(const Args&) { throw UsageError("benchmark 'stack' is not implemented yet"); }

}  // namespace st::app

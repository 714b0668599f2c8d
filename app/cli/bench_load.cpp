#include "cli_args.hpp"
#include "commands.hpp"

namespace st::app {

int benchLoad(const Args&) { throw UsageError("benchmark 'load' is not implemented yet"); }

}  // namespace st::app

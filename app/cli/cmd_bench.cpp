#include "cli_args.hpp"
#include "commands.hpp"

namespace st::app {

int cmdBench(const Args&) { throw UsageError("'bench' is not implemented yet"); }

}  // namespace st::app

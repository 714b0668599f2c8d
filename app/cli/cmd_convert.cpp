#include "cli_args.hpp"
#include "commands.hpp"

namespace st::app {

int cmdConvert(const Args&) { throw UsageError("'convert' is not implemented yet"); }

}  // namespace st::app

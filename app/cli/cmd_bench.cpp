#include <cstdio>
#include <string>

#include "cli_args.hpp"
#include "commands.hpp"

namespace st::app {

int cmdBench(const Args& args) {
  struct Entry {
    const char* name;
    int (*run)(const Args&);
    const char* summary;
  };
  static constexpr Entry kBenches[] = {
      {"load", benchLoad, "read 1500 frames of 512x512 float32 from page cache (MB/s)"},
      {"preprocess", benchPreprocess, "full pre-processing of paper-neo (500 x 512^2)"},
      {"stack", benchStack, "one IPSA and one CSA stack of 500 x 512^2"},
      {"search", benchSearch, "velocity search, the paper's problem or a smaller one"},
      {"fit", benchFit, "co-moving PSF fit"},
      {"memory", benchMemory, "out-of-core vs in-memory search: peak memory and time"},
  };
  if (args.empty() || args[0] == "--help") {
    std::printf("usage: synthtrack-cli bench WHAT [options]\n\n");
    for (const auto& b : kBenches)
      std::printf("  %-11s %s\n", b.name, b.summary);
    return args.empty() ? 2 : 0;
  }
  for (const auto& b : kBenches) {
    if (args[0] == b.name) return b.run(Args(args.begin() + 1, args.end()));
  }
  throw UsageError("unknown benchmark '" + args[0] + "'");
}

}  // namespace st::app

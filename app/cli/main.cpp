// synthtrack-cli: the batch front end. Runs the same core pipeline as the GUI.
#include <cstdio>
#include <exception>
#include <string>
#include <vector>

#include "cli_args.hpp"
#include "commands.hpp"
#include "st/common/error.hpp"
#include "st/config.hpp"
#include "terminal_progress.hpp"

namespace {

struct Command {
  const char* name;
  int (*run)(const st::app::Args&);
  const char* summary;
};

constexpr Command kCommands[] = {
    {"demo", st::app::cmdDemo, "simulate the paper's observation (paper-neo) and run the whole pipeline"},
    {"simulate", st::app::cmdSimulate, "write a synthetic observation (FITS cube + truth JSON)"},
    {"info", st::app::cmdInfo, "describe frames: size, BITPIX, times, cadence, WCS, warnings"},
    {"convert", st::app::cmdConvert, "load frames (cube, files or folder) and write one FITS cube"},
    {"preprocess", st::app::cmdPreprocess, "calibrate, remove background and static sources"},
    {"solve", st::app::cmdSolve, "plate-solve frames without a WCS (astrometry.net's solve-field)"},
    {"stack", st::app::cmdStack, "IPSA or CSA stack at one velocity"},
    {"search", st::app::cmdSearch, "velocity search: candidates and the velocity map"},
    {"batch", st::app::cmdBatch, "many observations: search --fit on each (MPI optional), merged catalogue"},
    {"fit", st::app::cmdFit, "co-moving PSF fit of one candidate"},
    {"report", st::app::cmdReport, "vetting session, DS9 regions, ADES PSV and MPC 80-column astrometry"},
    {"inject", st::app::cmdInject, "copies of raw frames with synthetic movers added, and their truth"},
    {"recovery", st::app::cmdRecovery, "score a search of injected frames: completeness, SNR ratio, SVG"},
    {"bench", st::app::cmdBench, "benchmarks (load, pre-processing, stacks, search)"},
};

void printUsage(std::FILE* out) {
  std::fprintf(out, "synthtrack-cli %s - synthetic tracking of faint, fast-moving asteroids\n\n", ST_VERSION);
  std::fprintf(out, "usage: synthtrack-cli COMMAND [options]   (COMMAND --help for its options)\n\n");
  for (const auto& c : kCommands)
    std::fprintf(out, "  %-11s %s\n", c.name, c.summary);
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> args(argv + 1, argv + argc);
  if (args.empty() || args[0] == "--help" || args[0] == "-h" || args[0] == "help") {
    printUsage(args.empty() ? stderr : stdout);
    return args.empty() ? 2 : 0;
  }
  if (args[0] == "--version") {
    std::printf("synthtrack-cli %s\n", ST_VERSION);
    return 0;
  }
  st::app::installSigintCancel();
  for (const auto& c : kCommands) {
    if (args[0] != c.name) continue;
    const st::app::Args rest(args.begin() + 1, args.end());
    try {
      return c.run(rest);
    } catch (const st::app::UsageError& e) {
      std::fprintf(stderr, "synthtrack-cli %s: %s (see synthtrack-cli %s --help)\n", c.name, e.what(),
                   c.name);
      return 2;
    } catch (const st::Cancelled&) {
      std::fprintf(stderr, "synthtrack-cli %s: cancelled\n", c.name);
      return 130;
    } catch (const std::exception& e) {
      std::fprintf(stderr, "synthtrack-cli %s: error: %s\n", c.name, e.what());
      return 1;
    }
  }
  std::fprintf(stderr, "synthtrack-cli: unknown command '%s'\n\n", args[0].c_str());
  printUsage(stderr);
  return 2;
}

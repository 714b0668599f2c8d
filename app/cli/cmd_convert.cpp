// synthtrack-cli convert INPUT... -o cube.fits: load frames (cube, files or folder) and write one cube.
#include <cstdio>

#include "cli_args.hpp"
#include "commands.hpp"
#include "load_args.hpp"
#include "st/io/fits_reader.hpp"
#include "st/io/fits_writer.hpp"
#include "terminal_progress.hpp"

namespace st::app {

int cmdConvert(const Args& args) {
  if (!args.empty() && args[0] == "--help") {
    std::printf(
        "usage: synthtrack-cli convert INPUT... -o CUBE.fits [options]\n\n"
        "Loads frames (a 3-D cube, 2-D files or folders; sorted by time) and writes one float32 cube with\n"
        "a FRAMES table of mid-times, exposures and origins.\n\n  -o CUBE.fits         output file "
        "(overwritten)\n%s",
        loadOptionsHelp());
    return 0;
  }
  auto names = loadOptionNames();
  names.insert("o");
  const CliArgs cli(args, names, {});
  if (cli.positionals().empty()) throw UsageError("give at least one INPUT (a FITS file or a folder)");
  const auto out = cli.value("o");
  if (!out) throw UsageError("give the output file with -o CUBE.fits");
  const io::LoadOptions options = loadOptionsFromArgs(cli);
  TerminalProgress progress;
  const FrameCube cube = io::loadFrames(cli.positionals(), options, progress, processCancelToken());
  io::writeCube(*out, cube, io::provenanceCards("convert"));
  progress.finish();
  for (const auto& w : cube.warnings)
    std::fprintf(stderr, "warning: %s\n", w.c_str());
  std::printf("wrote %s: %zu frames of %d x %d px\n", out->c_str(), cube.frameCount(), cube.width(),
              cube.height());
  return 0;
}

}  // namespace st::app

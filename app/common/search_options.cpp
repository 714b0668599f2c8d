#include "search_options.hpp"

#include <cstdio>
#include <filesystem>

#include "plate_solve_args.hpp"
#include "st/common/memory_budget.hpp"

namespace st::app {

namespace {

Velocity parsePair(const std::string& text, const std::string& name) {
  double a = 0.0, b = 0.0;
  char comma = 0;
  if (std::sscanf(text.c_str(), "%lf%c%lf", &a, &comma, &b) != 3 || comma != ',') {
    throw UsageError("--" + name + " needs VX,VY, got '" + text + "'");
  }
  return {a, b};
}

}  // namespace

std::set<std::string> searchFlagNames() {
  std::set<std::string> flags = {"grid-step-fwhm", "grid-auto", "no-register", "plate-solve", "keep-scratch"};
  flags.merge(plateSolveFlagNames());
  return flags;
}

std::set<std::string> searchOptionNames() {
  std::set<std::string> names = plateSolveOptionNames();
  names.merge(std::set<std::string>{"vmax-px-s", "vmax-arcsec-min", "vmax-deg-day", "centre-px-s",
                                    "grid-step-px", "snr", "fap", "min-frame-fraction", "max-candidates",
                                    "sigma-f", "fwhm", "backend", "frame-precision", "method", "fit-max",
                                    "memory-limit", "scratch"});
  return names;
}

const char* searchOptionsHelp() {
  return "  --vmax-px-s V | --vmax-arcsec-min A | --vmax-deg-day D\n"
         "                        half-width of the grid around its centre (default: 12 deg/day, the "
         "paper's,\n"
         "                        when the plate scale is known)\n"
         "  --grid-auto           half-width from the data, as the GUI's default: the smallest of 12 deg/day,\n"
         "                        what stays in the frame, and about a minute of exact search on this backend\n"
         "  --centre-px-s VX,VY   grid centre (default: the sky rate)\n"
         "  --grid-step-px P      grid step = P px of motion over the time span (default 1, the paper's "
         "rule)\n"
         "  --grid-step-fwhm      grid step = PSF FWHM over the time span (the paper's coarsest)\n"
         "  --no-register         raw input: no per-frame registration in pre-processing (the linear sky\n"
         "                        rate is the model even where the star field jumps)\n"
         "  --plate-solve         raw input without a WCS: plate-solve the first frame with astrometry.net\n"
         "                        (--solve-scale, --solve-ra/--solve-dec, --solve-time-limit, --index-dir;\n"
         "                        `synthtrack-cli solve --help`), so that fits get RA/Dec and reports ADES\n"
         "  --snr S | --fap P     threshold: SNR (default 7) or target false-alarm probability over all "
         "trials\n"
         "  --min-frame-fraction F  ignore cells seen by fewer than F x frames (default 0.5)\n"
         "  --max-candidates N    cells kept before clustering (default 2000000)\n"
         "  --sigma-f S           noise of one filtered frame (default: header SIGMAF of a filtered cube, "
         "else\n"
         "                        measured from the filtered frames: 1.4826 MAD)\n"
         "  --fwhm PX             PSF FWHM (default: fitted, or header PSFFWHM with --preprocessed; for a\n"
         "                        zero-biased cube it is the matched filter's)\n"
         "  --fit-max N           candidates refined by the co-moving fit (default 50)\n"
         "  --memory-limit SIZE   memory budget, e.g. 8G or 500M (default: 70% of the memory available now,\n"
         "                        within the cgroup's limit). The peak is estimated and printed before any\n"
         "                        work; a pre-processed cube that does not fit is searched out of core in\n"
         "                        tiles (the same candidates); raw frames that do not fit are pre-processed\n"
         "                        out of core in strips of rows into a filtered cube in --scratch (no --fit);\n"
         "                        what cannot fit stops with exit 1 before the work\n"
         "  --scratch DIR         where that filtered cube is written (default: the current directory); it is\n"
         "                        removed after the search unless --keep-scratch (then search it again with\n"
         "                        --preprocessed)\n"
         "  --backend auto|cpu|cuda  (default auto)\n"
         "  --frame-precision fp32|fp16  filtered frames on the GPU in float32 (default) or float16: the\n"
         "                        CUDA exact search 1.27x faster, SNR within 6.4e-4 relative of fp32 on the\n"
         "                        paper's problem (printed with the backend); the CPU ignores it\n"
         "  --method auto|exact|tree  exact IPSA (every frame at its exact shift) or the hierarchical tree "
         "search\n"
         "                        (about N_pix x N_v work instead of N_pix x N_f x N_v; every sample within "
         "1 px\n"
         "                        of the exact shift, median SNR loss ~1%, worst ~5%). auto (default): the "
         "tree\n"
         "                        where the backend has it and it is estimated >= 2x faster and >= 1 s "
         "quicker,\n"
         "                        else exact; the choice and why are printed and written to the JSON and "
         "CSV\n";
}

SearchOptions parseSearchOptions(const CliArgs& cli) {
  SearchOptions o;
  search::GridSpec& g = o.request.grid;
  const int ranges = cli.has("vmax-px-s") + cli.has("vmax-arcsec-min") + cli.has("vmax-deg-day");
  if (ranges > 1) throw UsageError("give one of --vmax-px-s, --vmax-arcsec-min, --vmax-deg-day");
  o.autoGrid = cli.flag("grid-auto");
  if (o.autoGrid && ranges > 0) throw UsageError("give --grid-auto or a --vmax-* half-width, not both");
  if (o.autoGrid && cli.flag("grid-step-fwhm")) throw UsageError("--grid-auto takes --grid-step-px, not --grid-step-fwhm");
  g.unit = search::VelocityUnit::DegPerDay;
  g.halfRange = 12.0;
  if (auto v = cli.number("vmax-px-s")) g = {*v, search::VelocityUnit::PxPerS};
  if (auto v = cli.number("vmax-arcsec-min")) g = {*v, search::VelocityUnit::ArcsecPerMin};
  if (auto v = cli.number("vmax-deg-day")) g = {*v, search::VelocityUnit::DegPerDay};
  if (auto c = cli.value("centre-px-s")) g.centre = parsePair(*c, "centre-px-s");
  if (cli.flag("grid-step-fwhm")) {
    if (cli.has("grid-step-px")) throw UsageError("give --grid-step-px or --grid-step-fwhm, not both");
    g.stepRule = search::StepRule::FwhmOverSpan;
  }
  if (auto p = cli.number("grid-step-px")) g.stepPx = *p;
  search::SearchParams& p = o.request.params;
  if (cli.has("snr") && cli.has("fap")) throw UsageError("give --snr or --fap, not both");
  if (auto s = cli.number("snr")) p.snrThreshold = *s;
  p.targetFap = cli.number("fap");
  if (auto f = cli.number("min-frame-fraction")) p.minFrameFraction = *f;
  if (auto n = cli.integer("max-candidates")) {
    if (*n < 1) throw UsageError("--max-candidates must be >= 1");
    p.maxCandidates = static_cast<std::size_t>(*n);
  }
  o.registerFrames = !cli.flag("no-register");
  o.plateSolve = cli.flag("plate-solve");
  o.plateSolveParams = plateSolveParamsFromArgs(cli);
  o.sigmaF = cli.number("sigma-f");
  o.fwhm = cli.number("fwhm");
  if (auto b = cli.value("backend")) o.backend = *b;
  if (auto f = cli.value("frame-precision")) {
    if (*f != "fp32" && *f != "fp16")
      throw UsageError("--frame-precision must be fp32 or fp16, got '" + *f + "'");
    o.framePrecision = *f;
  }
  p.method = search::SearchMethod::Auto;
  if (auto m = cli.value("method")) {
    const auto method = search::parseSearchMethod(*m);
    if (!method) throw UsageError("--method must be 'auto', 'exact' or 'tree', got '" + *m + "'");
    p.method = *method;
  }
  if (auto m = cli.value("memory-limit")) {
    parseMemorySize(*m);  // refuse a bad size before any work
    o.memoryLimit = *m;
  }
  if (auto d = cli.value("scratch")) {
    if (!std::filesystem::is_directory(*d)) throw UsageError("--scratch " + *d + ": not a directory");
    o.scratchDir = *d;
  }
  o.keepScratch = cli.flag("keep-scratch");
  if (auto n = cli.integer("fit-max")) {
    if (*n < 0) throw UsageError("--fit-max must be >= 0");
    o.fitMax = *n;
  }
  return o;
}

}  // namespace st::app

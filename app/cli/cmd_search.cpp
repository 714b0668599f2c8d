// synthtrack-cli search INPUT... : the velocity search (paper §4.4) over a grid of trial velocities,
// candidates above threshold with their false-alarm probabilities (paper Prob_false).
#include <cmath>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>

#include "backend_factory.hpp"
#include "candidate_fit.hpp"
#include "st/pipeline/preprocess.hpp"
#include "cli_args.hpp"
#include "commands.hpp"
#include "st/report/search_report.hpp"
#include "load_args.hpp"
#include "st/common/error.hpp"
#include "st/common/parallel.hpp"
#include "st/io/fits_reader.hpp"
#include "st/search/method_choice.hpp"
#include "st/search/search_run.hpp"
#include "st/search/sky_motion.hpp"
#include "st/search/velocity_grid.hpp"
#include "st/stack/matched_filter.hpp"
#include "terminal_progress.hpp"

namespace st::app {
namespace {

constexpr const char* kHelp =
    "usage: synthtrack-cli search INPUT... [--preprocessed] [--fit] [options]\n"
    "  Searches the frames over a grid of trial velocities (paper §4.4). Raw INPUT is\n"
    "  pre-processed first (as 'synthtrack-cli preprocess' with its defaults: no bias/flat frames).\n"
    "  --preprocessed        INPUT is already pre-processed and matched-filtered; sigma_F, PSF FWHM and sky\n"
    "                        rate come from the header keywords SIGMAF, PSFFWHM, SKYVX/SKYVY (px/s) when\n"
    "                        present, else from the options below\n"
    "  --fit                 refine every candidate (up to --fit-max, default 50) by the co-moving PSF fit\n"
    "                        with segment checks (needs raw INPUT, not --preprocessed)\n"
    "  --vmax-px-s V | --vmax-arcsec-min A | --vmax-deg-day D\n"
    "                        half-width of the grid around its centre (default: 12 deg/day, the paper's,\n"
    "                        when the plate scale is known)\n"
    "  --centre-px-s VX,VY   grid centre (default: the sky rate)\n"
    "  --grid-step-px P      grid step = P px of motion over the time span (default 1, the paper's rule)\n"
    "  --grid-step-fwhm      grid step = PSF FWHM over the time span (the paper's coarsest)\n"
    "  --snr S | --fap P     threshold: SNR (default 7) or target false-alarm probability over all trials\n"
    "  --min-frame-fraction F  ignore cells seen by fewer than F x frames (default 0.5)\n"
    "  --max-candidates N    cells kept before clustering (default 2000000)\n"
    "  --sigma-f S           noise of one filtered frame (default: header SIGMAF, else measured: 1.4826 "
    "MAD)\n"
    "  --fwhm PX             PSF FWHM (default: header PSFFWHM, else 3)\n"
    "  --backend auto|cpu|cuda  (default auto)\n"
    "  --method auto|exact|tree  exact IPSA (every frame at its exact shift) or the hierarchical tree "
    "search\n"
    "                        (about N_pix x N_v work instead of N_pix x N_f x N_v; every sample within 1 px\n"
    "                        of the exact shift, median SNR loss ~1%, worst ~5%). auto (default): the tree\n"
    "                        where the backend has it and it is estimated >= 2x faster and >= 1 s quicker,\n"
    "                        else exact; the choice and why are printed and written to the JSON and CSV\n"
    "  --out FILE.csv        write the candidates as CSV    --json  print JSON on stdout\n";

struct Options {
  search::SearchRequest request;
  std::optional<double> sigmaF;
  std::optional<double> fwhm;
  std::string backend = "auto";
  std::optional<std::string> csv;
  bool json = false;
};

Velocity parsePair(const std::string& text, const std::string& name) {
  double a = 0.0, b = 0.0;
  char comma = 0;
  if (std::sscanf(text.c_str(), "%lf%c%lf", &a, &comma, &b) != 3 || comma != ',') {
    throw UsageError("--" + name + " needs VX,VY, got '" + text + "'");
  }
  return {a, b};
}

Options parseOptions(const CliArgs& cli) {
  Options o;
  search::GridSpec& g = o.request.grid;
  const int ranges = cli.has("vmax-px-s") + cli.has("vmax-arcsec-min") + cli.has("vmax-deg-day");
  if (ranges > 1) throw UsageError("give one of --vmax-px-s, --vmax-arcsec-min, --vmax-deg-day");
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
  o.sigmaF = cli.number("sigma-f");
  o.fwhm = cli.number("fwhm");
  if (auto b = cli.value("backend")) o.backend = *b;
  p.method = "auto";
  if (auto m = cli.value("method")) {
    if (*m != "auto" && *m != "exact" && *m != "tree")
      throw UsageError("--method must be 'auto', 'exact' or 'tree', got '" + *m + "'");
    p.method = *m;
  }
  o.csv = cli.value("out");
  o.json = cli.flag("json");
  return o;
}

search::FilteredCube loadFiltered(const CliArgs& cli, const Options& o, ProgressSink& progress) {
  search::FilteredCube fc;
  SubProgress loadProgress(progress, 0.0, 1.0);
  fc.frames = io::loadFrames(cli.positionals(), loadOptionsFromArgs(cli), loadProgress, processCancelToken());
  const FitsHeader& h = fc.frames.header;
  fc.psfFwhmPx = o.fwhm.value_or(h.getDouble("PSFFWHM").value_or(3.0));
  if (!(fc.psfFwhmPx > 0.0)) throw InputError("PSF FWHM must be > 0, got " + std::to_string(fc.psfFwhmPx));
  fc.skyRate = {h.getDouble("SKYVX").value_or(0.0), h.getDouble("SKYVY").value_or(0.0)};
  if (o.sigmaF) {
    fc.sigmaF = *o.sigmaF;
  } else if (auto s = h.getDouble("SIGMAF")) {
    fc.sigmaF = *s;
  } else {
    fc.sigmaF = stack::measureFilteredNoise(fc.frames, static_cast<int>(std::ceil(2.0 * fc.psfFwhmPx)));
    if (!(fc.sigmaF > 0.0)) {
      throw InputError(
          "could not measure sigma_F from the data (fewer than 1000 usable pixels); give --sigma-f");
    }
  }
  return fc;
}

/// Both methods' estimates, the chosen one marked, and the choice with its reason (stderr, before the run).
void printEstimate(const search::FilteredCube& fc, const search::VelocityGrid& grid,
                   const search::MethodEstimate& e, const search::MethodChoice& choice) {
  const double mb = 1048576.0;
  std::fprintf(stderr, "search: %d x %d px, %zu frames, %d x %d velocities (step %.4g px/s); cube %.0f MB\n",
               fc.frames.width(), fc.frames.height(), fc.frames.frameCount(), grid.nvx, grid.nvy,
               grid.stepPxS, e.cubeBytes / mb);
  const bool tree = choice.method == "tree";
  std::fprintf(stderr, "  %s exact: %.3g additions, %.0f MB working, estimate %.3g s\n", tree ? " " : ">",
               e.exactAdditions, e.exactWorkingBytes / mb, e.exactSeconds);
  if (e.treeAdditions > 0.0) {
    std::fprintf(
        stderr,
        "  %s tree:  %.3g additions (%.0fx fewer), %.0f MB working (tiles of %d rows), estimate %.3g "
        "s\n",
        tree ? ">" : " ", e.treeAdditions, e.exactAdditions / e.treeAdditions, e.treeWorkingBytes / mb,
        e.treeTileRows, e.treeSeconds);
  }
  std::fprintf(stderr, "method: %s (%s)\n", choice.method.c_str(), choice.reason.c_str());
}

void printTable(const nlohmann::json& j) {
  std::printf("t_ref %s (MJD %.8f), %s, method %s, trials %lld x %lld x %lld x %lld, SNR threshold %.3f\n",
              j["t_ref_utc"].get<std::string>().c_str(), j["t_ref_mjd"].get<double>(),
              j["backend"].get<std::string>().c_str(), j["method"].get<std::string>().c_str(),
              j["trials"]["nx"].get<long long>(), j["trials"]["ny"].get<long long>(),
              j["trials"]["nvx"].get<long long>(), j["trials"]["nvy"].get<long long>(),
              j["snr_threshold"].get<double>());
  std::printf("%zu candidates\n", j["candidates"].size());
  if (j["candidates"].empty()) return;
  std::printf("%6s %6s %10s %10s %8s %6s %10s %10s %8s\n", "x", "y", "vx_px_s", "vy_px_s", "snr", "nIn",
              "fap", "deg_day", "pa_deg");
  for (const auto& c : j["candidates"]) {
    std::printf("%6d %6d %10.5f %10.5f %8.2f %6d %10.3g %10s %8s\n", c["x"].get<int>(), c["y"].get<int>(),
                c["vx_px_s"].get<double>(), c["vy_px_s"].get<double>(), c["snr"].get<double>(),
                c["n_frames"].get<int>(), c["fap"].get<double>(),
                c.contains("rate_deg_day") ? std::to_string(c["rate_deg_day"].get<double>()).c_str() : "-",
                c.contains("pa_deg") ? std::to_string(c["pa_deg"].get<double>()).c_str() : "-");
  }
}

}  // namespace

int cmdSearch(const Args& args) {
  std::set<std::string> valued = {"vmax-px-s",
                                  "vmax-arcsec-min",
                                  "vmax-deg-day",
                                  "centre-px-s",
                                  "grid-step-px",
                                  "snr",
                                  "fap",
                                  "min-frame-fraction",
                                  "max-candidates",
                                  "sigma-f",
                                  "fwhm",
                                  "backend",
                                  "method",
                                  "fit-max",
                                  "out"};
  for (const auto& n : loadOptionNames())
    valued.insert(n);
  auto flags = calibFlagNames();
  flags.insert({"preprocessed", "grid-step-fwhm", "json", "fit", "help"});
  const CliArgs cli(args, valued, flags);
  if (cli.flag("help")) {
    std::printf("%s%s%s", kHelp, calibOptionsHelp(), loadOptionsHelp());
    return 0;
  }
  if (cli.positionals().empty()) throw UsageError("no INPUT given");
  const bool preprocessed = cli.flag("preprocessed");
  if (cli.flag("fit") && preprocessed) {
    throw UsageError("--fit needs the unfiltered frames: give the raw INPUT without --preprocessed");
  }
  const Options o = parseOptions(cli);
  BackendSelection sel = makeBackendForMethod(parseBackendChoice(o.backend), o.request.params.method);
  TerminalProgress progress;
  std::optional<pipeline::Prepared> prepared;
  if (!preprocessed) {
    SubProgress loadProgress(progress, 0.0, 0.2);
    FrameCube raw =
        io::loadFrames(cli.positionals(), loadOptionsFromArgs(cli), loadProgress, processCancelToken());
    SubProgress prepProgress(progress, 0.2, 0.5);
    std::vector<std::string> warnings = raw.warnings;
    pipeline::PreprocessParams pp;
    pp.calib = calibParamsFromArgs(cli);
    prepared = pipeline::preprocess(std::move(raw), pp, prepProgress, processCancelToken());
    warnings.insert(warnings.end(), prepared->calibration.warnings.begin(),
                    prepared->calibration.warnings.end());
    printWarnings(warnings);
    if (o.fwhm) prepared->filtered.psfFwhmPx = *o.fwhm;
    if (o.sigmaF) prepared->filtered.sigmaF = *o.sigmaF;
  }
  const search::FilteredCube loaded = preprocessed ? loadFiltered(cli, o, progress) : search::FilteredCube{};
  const search::FilteredCube& fc = preprocessed ? loaded : prepared->filtered;
  const search::VelocityGrid grid = search::makeVelocityGrid(o.request.grid, fc);
  const search::MethodEstimate e =
      search::estimateMethods(fc.frames.width(), fc.frames.height(), fc.frames.timeOffsetsS(), grid,
                              search::costModelFor(*sel.backend), workerCount());
  const search::MethodChoice method = search::chooseMethod(
      o.request.params.method, e, sel.backend->supportsMethod("tree"), sel.backend->name());
  progress.finish();
  std::fprintf(stderr, "%s\n", sel.message.c_str());
  printEstimate(fc, grid, e, method);
  const search::SearchResult r = search::searchWithChoice(*sel.backend, fc, grid, o.request.params, method,
                                                          progress, processCancelToken());
  progress.finish();
  std::fputs(searchNotesText(r).c_str(), stderr);
  nlohmann::json j = report::searchResultToJson(fc, r, cli.positionals());
  j["t_ref_utc"] = isoFromMjd(r.tRefMjd);
  j["min_frames"] = r.minFrames;
  j["cells_above_threshold"] = r.cellsAboveThreshold;
  if (cli.flag("fit")) {
    const double gain = prepared->frames.header.getDouble("GAIN").value_or(1.0);
    const long long fitMax = cli.integer("fit-max").value_or(50);
    for (std::size_t i = 0; i < r.candidates.size() && static_cast<long long>(i) < fitMax; ++i) {
      progress.report(static_cast<double>(i) / static_cast<double>(r.candidates.size()), "co-moving fits");
      j["candidates"][i]["fit"] = fitCandidateJson(*prepared, r.candidates[i], gain, processCancelToken());
    }
    progress.finish();
  }
  if (o.csv) report::writeCandidatesCsv(*o.csv, j);
  if (o.json) {
    std::printf("%s\n", j.dump(2).c_str());
  } else {
    printTable(j);
  }
  return 0;
}

}  // namespace st::app

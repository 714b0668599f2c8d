// synthtrack-cli search INPUT... : the velocity search (paper §4.4) over a grid of trial velocities,
// candidates above threshold with their false-alarm probabilities (paper Prob_false).
#include <cstdio>
#include <fstream>
#include <string>
#include <nlohmann/json.hpp>

#include "backend_factory.hpp"
#include "observation_pipeline.hpp"
#include "search_options.hpp"
#include "cli_args.hpp"
#include "commands.hpp"
#include "st/common/memory_budget.hpp"
#include "st/report/search_report.hpp"
#include "load_args.hpp"
#include "st/search/method_choice.hpp"
#include "st/search/sky_motion.hpp"
#include "step_timings.hpp"
#include "terminal_progress.hpp"

namespace st::app {
namespace {

constexpr const char* kHelp =
    "usage: synthtrack-cli search INPUT... [--preprocessed] [--fit] [options]\n"
    "  Searches the frames over a grid of trial velocities (paper §4.4). Raw INPUT is\n"
    "  pre-processed first (as 'synthtrack-cli preprocess' with its defaults).\n"
    "  --bias F / --flat F / --dark F   calibration frames of raw INPUT (files or folders; repeat for "
    "several)\n"
    "  --preprocessed        INPUT was written by 'synthtrack-cli preprocess', told by its header: the\n"
    "                        zero-biased cube (-o; STFILT = F) is matched-filtered with the header's PSF\n"
    "                        (PSFFWHM, PSFBETA) first, the filtered cube (--filtered; STFILT = T) is "
    "searched\n"
    "                        as is with SIGMAF; sky rate from SKYVX/SKYVY (px/s). A cube whose header does "
    "not\n"
    "                        say (no STFILT) is refused; a pre-processed cube without --preprocessed too\n"
    "  --fit                 refine every candidate (up to --fit-max, default 50) by the co-moving PSF fit\n"
    "                        with segment checks (needs raw INPUT, not --preprocessed)\n"
    "  --mpi                 under mpirun: split the velocity grid's vy rows over the ranks (exact CPU "
    "search),\n"
    "                        rank 0 gathers; the same candidates as one process\n"
    "  --out FILE.csv        write the candidates as CSV    --json  print JSON on stdout\n"
    "  --timings             print on stderr when each step ended, seconds from the start (backend, memory\n"
    "                        plan, loaded and pre-processed with each stage's seconds and the\n"
    "                        pre-processing's notes (where each stage ran: CPU or device, and its parts),\n"
    "                        search planned, searched, outputs)\n";

/// Both methods' estimates, the chosen one marked, and the choice with its reason (stderr, before the run).
void printEstimate(const PlannedSearch& p) {
  const search::FilteredCube& fc = p.cube;
  const search::VelocityGrid& grid = p.grid;
  const search::MethodEstimate& e = p.estimate;
  const search::MethodChoice& choice = p.choice;
  const double mb = 1048576.0;
  std::fprintf(stderr, "search: %d x %d px, %zu frames, %d x %d velocities (step %.4g px/s); cube %.0f MB\n",
               p.width, p.height, fc.frames.frameCount(), grid.nvx, grid.nvy,
               grid.stepPxS, e.cubeBytes / mb);
  const bool tree = choice.method == search::SearchMethod::Tree;
  std::fprintf(stderr, "  %s exact: %.3g additions, %.0f MB working, estimate %.3g s\n", tree ? " " : ">",
               e.exactAdditions, e.exactWorkingBytes / mb, e.exactSeconds);
  if (e.treeAdditions > 0.0) {
    std::fprintf(
        stderr,
        "  %s tree:  %.3g additions (%.0fx fewer), %.0f MB working (tiles of %d rows%s), estimate %.3g "
        "s\n",
        tree ? ">" : " ", e.treeAdditions, e.exactAdditions / e.treeAdditions, e.treeWorkingBytes / mb,
        e.treeTileRows,
        e.treeBlocks > 1 ? (", " + std::to_string(e.treeBlocks) + " velocity blocks").c_str() : "",
        e.treeSeconds);
  }
  std::fprintf(stderr, "method: %s (%s)\n", std::string(choice.method.name()).c_str(), choice.reason.c_str());
  if (const std::string w = search::longSearchWarning(e, choice, grid); !w.empty())
    std::fprintf(stderr, "warning: %s\n", w.c_str());
}

/// Memory plan lines from `from` on.
void printMemory(const MemoryPlan& m, std::size_t& printed) {
  for (; printed < m.lines.size(); ++printed)
    std::fprintf(stderr, "memory: %s\n", m.lines[printed].c_str());
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
  std::set<std::string> valued = searchOptionNames();
  valued.insert({"out", "bias", "flat", "dark"});
  for (const auto& n : loadOptionNames())
    valued.insert(n);
  auto flags = calibFlagNames();
  flags.merge(searchFlagNames());
  flags.insert({"preprocessed", "json", "fit", "mpi", "timings", "help"});
  const CliArgs cli(args, valued, flags);
  if (cli.flag("help")) {
    std::printf("%s%s%s%s", kHelp, searchOptionsHelp(), calibOptionsHelp(), loadOptionsHelp());
    return 0;
  }
  if (cli.positionals().empty()) throw UsageError("no INPUT given");
  ObservationInput input{
      cli.positionals(),  loadOptionsFromArgs(cli), cli.flag("preprocessed"),
      cli.values("bias"), cli.values("dark"),       cli.values("flat"),
      calibParamsFromArgs(cli)};
  if (input.preprocessed && !(input.bias.empty() && input.dark.empty() && input.flat.empty()))
    throw UsageError("--bias/--flat/--dark calibrate raw INPUT: a --preprocessed cube is calibrated already");
  if (cli.flag("fit") && input.preprocessed) {
    throw UsageError("--fit needs the unfiltered frames: give the raw INPUT without --preprocessed");
  }
  const SearchOptions o = parseSearchOptions(cli);
  if (cli.flag("mpi")) return searchMpi(input, o, cli.flag("fit"), cli.value("out"), cli.flag("json"));
  const StepTimings timings(cli.flag("timings"));
  // Made on another thread while the frames are read (issue 16: a CUDA context takes ~0.2 s).
  BackendInTheMaking backendMade(parseBackendChoice(o.backend), o.request.params.method,
                                 parseFramePrecision(o.framePrecision));
  BackendSelection* selMade = nullptr;
  auto backend = [&]() -> search::SearchBackend& {
    if (!selMade) {
      selMade = &backendMade.get();
      timings.mark("backend ready");
    }
    return *selMade->backend;
  };
  TerminalProgress progress;
  ObservationHooks hooks;
  std::size_t memoryLines = 0;
  hooks.memory = [&](const MemoryPlan& m) {
    timings.mark("memory plan");
    printMemory(m, memoryLines);
  };
  hooks.prepared = [&](const pipeline::Prepared& prep) {
    if (!timings.on()) return;
    progress.finish();
    timings.stages(prep.stageSeconds);
    for (const std::string& n : prep.notes)
      std::fprintf(stderr, "timings:   note: %s\n", n.c_str());
    timings.mark("loaded and pre-processed");
  };
  hooks.planned = [&](const PlannedSearch& p) {
    progress.finish();
    timings.mark("search planned");
    for (const auto& w : p.warnings)
      std::fprintf(stderr, "warning: %s\n", w.c_str());
    for (const auto& n : p.notes)
      std::fprintf(stderr, "note: %s\n", n.c_str());
    std::fprintf(stderr, "note: %s\n", search::staticRateLimitNote(p.cube.frames, p.cube.psfFwhmPx).c_str());
    std::fprintf(stderr, "%s\n", backendMade.get().message.c_str());
    printEstimate(p);
    printMemory(p.memory, memoryLines);
  };
  hooks.searched = [&](const search::SearchResult& r) {
    progress.finish();
    timings.mark("searched");
    std::fputs(searchNotesText(r).c_str(), stderr);
  };
  const nlohmann::json j =
      runObservation(input, o, cli.flag("fit"), backend, progress, processCancelToken(), hooks);
  progress.finish();
  std::fprintf(stderr, "memory: peak resident %s\n",
               formatBytes(static_cast<double>(peakResidentBytes())).c_str());
  timings.mark("candidates measured");
  writeSearchOutputs(j, cli.value("out"), cli.flag("json"));
  timings.mark("outputs written");
  return 0;
}

void writeSearchOutputs(const nlohmann::json& j, const std::optional<std::string>& csv, bool json) {
  if (csv) report::writeCandidatesCsv(*csv, j);
  if (json) {
    std::printf("%s\n", j.dump(2).c_str());
  } else {
    printTable(j);
  }
}

}  // namespace st::app

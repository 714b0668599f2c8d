// `synthtrack-cli demo`: the whole pipeline on the built-in demo observation (the paper's detection,
// simulated): simulate(paper-neo) -> pre-process -> velocity search -> co-moving fits with segment checks
// -> reports, then a comparison with the simulator's truth. Prints where everything went.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "backend_factory.hpp"
#include "st/candidate/candidate_fit.hpp"
#include "st/report/candidate_json.hpp"
#include "cli_args.hpp"
#include "commands.hpp"
#include "st/io/fits_writer.hpp"
#include "st/io/wcs.hpp"
#include "st/pipeline/demo_search.hpp"
#include "st/pipeline/prepared_json.hpp"
#include "st/pipeline/preprocess.hpp"
#include "st/report/search_report.hpp"
#include "st/search/method_choice.hpp"
#include "st/search/velocity_grid.hpp"
#include "st/sim/simulator.hpp"
#include "st/stack/ipsa.hpp"
#include "step_timings.hpp"
#include "terminal_progress.hpp"

namespace st::app {
namespace {

constexpr const char* kHelp =
    "usage: synthtrack-cli demo [--out DIR] [--preset NAME] [--seed N] [--frames N]\n"
    "                           [--vmax-deg-day D] [--grid-step-px P] [--snr S] [--fits K]\n"
    "                           [--backend auto|cpu|cuda] [--method auto|exact|tree]\n"
    "                           [--frame-precision fp32|fp16] [--timings]\n"
    "Simulates the demo observation (default paper-neo: the paper's V~23 asteroid at 5.97 deg/day, 500\n"
    "frames of 512x512 at 16.7 Hz, sky drifting 5\"/s; also known-pair and small), pre-processes it,\n"
    "searches +-D deg/day around the sky rate (default: the preset's, 8 for paper-neo, 1.5 for known-pair,\n"
    "40 for small) in steps of P px over the span (default 1.5; both demo settings, coarser than the\n"
    "paper's +-12 deg/day and 1 px that 'synthtrack-cli search' uses), with --method (default auto: exact\n"
    "or tree, whichever is estimated to win), fits the K best candidates (default 40) and writes\n"
    "everything to DIR (default ./demo-output). --frame-precision fp16: the CUDA exact search on float16\n"
    "frames (faster; its SNR cost is printed with the backend). --timings: when each step ended on stderr,\n"
    "and the seconds after the simulation (the demo's own work: pre-processing to outputs).\n";

struct DemoOptions {
  std::filesystem::path out = "demo-output";
  std::string preset = "paper-neo";
  std::uint64_t seed = 1;
  int frames = 0;
  double vmaxDegDay = 0.0;  ///< 0: the preset's (sim::presetDemoHalfRangeDegPerDay)
  double stepPx = sim::kDemoGridStepPx;
  double snr = pipeline::demoSearchParams().snrThreshold;
  int fits = 40;
  BackendChoice backend = BackendChoice::Auto;
  FramePrecisionChoice precision = FramePrecisionChoice::Fp32;
  search::SearchMethod method = pipeline::demoSearchParams().method;
  bool timings = false;
};

DemoOptions parseDemo(const Args& args) {
  const CliArgs cli(
      args,
      {"out", "preset", "seed", "frames", "vmax-deg-day", "grid-step-px", "snr", "fits", "backend", "method",
       "frame-precision"},
      {"help", "timings"});
  if (!cli.positionals().empty()) throw UsageError("unexpected argument '" + cli.positionals()[0] + "'");
  DemoOptions o;
  if (auto v = cli.value("out")) o.out = *v;
  o.timings = cli.flag("timings");
  if (auto v = cli.value("preset")) o.preset = *v;
  if (auto v = cli.integer("seed")) o.seed = static_cast<std::uint64_t>(*v);
  if (auto v = cli.integer("frames")) o.frames = static_cast<int>(*v);
  o.vmaxDegDay = cli.number("vmax-deg-day", sim::presetDemoHalfRangeDegPerDay(o.preset));
  o.stepPx = cli.number("grid-step-px", o.stepPx);
  o.snr = cli.number("snr", o.snr);
  if (auto v = cli.integer("fits")) o.fits = static_cast<int>(*v);
  if (auto v = cli.value("backend")) o.backend = parseBackendChoice(*v);
  if (auto v = cli.value("frame-precision")) o.precision = parseFramePrecision(*v);
  if (auto v = cli.value("method")) {
    const auto method = search::parseSearchMethod(*v);
    if (!method) throw UsageError("--method must be auto, exact or tree, got '" + *v + "'");
    o.method = *method;
  }
  if (!(o.vmaxDegDay > 0.0)) throw UsageError("--vmax-deg-day must be > 0");
  if (!(o.stepPx > 0.0)) throw UsageError("--grid-step-px must be > 0");
  if (o.fits < 0) throw UsageError("--fits must be >= 0");
  return o;
}

void writeStack(const std::filesystem::path& path, const FrameCube& cube, Velocity v,
                const std::string& what) {
  const stack::StackResult s = stack::stackIpsa(cube, v);
  FitsHeader h = io::provenanceCards("demo stack: " + what);
  if (cube.wcs) {
    for (const auto& card : cube.wcs->toHeader().cards)
      h.cards.push_back(card);
  }
  h.setNumber("STVX", v.vx, "stack velocity x [px/s]");
  h.setNumber("STVY", v.vy, "stack velocity y [px/s]");
  h.setNumber("TREFMJD", cube.tRefMjd(), "reference epoch, MJD (UTC), mean mid-time");
  io::writeImage(path.string(), s.sum, h);
}

/// The demo's search: +-vmax deg/day around the sky rate, steps of stepPx over the span, o.method.
search::SearchResult demoSearch(const DemoOptions& o, const pipeline::Prepared& prepared,
                                search::SearchBackend& backend, ProgressSink& progress, CancelToken& cancel) {
  // The settings the GUI's demo uses too (st/pipeline/demo_search.hpp), with the options' overrides.
  search::GridSpec spec = pipeline::demoGridSpec(prepared.frames.plateScaleArcsecPerPx);
  spec.halfRange = o.vmaxDegDay;
  spec.stepPx = o.stepPx;
  search::SearchParams params = pipeline::demoSearchParams();
  params.snrThreshold = o.snr;
  params.method = o.method;
  const search::VelocityGrid grid = search::makeVelocityGrid(spec, prepared.filtered);
  return search::searchWithMethod(backend, prepared.filtered, grid, params, progress, cancel);
}

/// The index of the candidate nearest the truth object in position and velocity, if one is near enough.
std::optional<std::size_t> matchTruth(const std::vector<search::Candidate>& candidates, const sim::TruthObject& t,
                                      double stepPxS) {
  std::optional<std::size_t> best;
  double bestD = 1e300;
  for (std::size_t i = 0; i < candidates.size(); ++i) {
    const search::Candidate& c = candidates[i];
    const double dPos = std::hypot(c.x - t.xRefPx, c.y - t.yRefPx);
    const double dVel = std::hypot(c.v.vx - t.vxPxPerS, c.v.vy - t.vyPxPerS);
    if (dPos <= 3.0 && dVel <= 2.0 * stepPxS && dPos < bestD) {
      best = i;
      bestD = dPos;
    }
  }
  return best;
}

}  // namespace

int cmdDemo(const Args& args) {
  if (std::find(args.begin(), args.end(), "--help") != args.end()) {
    std::printf("%s", kHelp);
    return 0;
  }
  const DemoOptions o = parseDemo(args);
  std::filesystem::create_directories(o.out);
  TerminalProgress progress;
  CancelToken& cancel = processCancelToken();
  const auto path = [&](const char* name) { return (o.out / name).string(); };
  const StepTimings timings(o.timings);
  // The backend (a CUDA context takes ~0.25 s) is made while the observation is simulated.
  BackendInTheMaking backendMade(o.backend, o.method, o.precision);

  // 1. The observation.
  sim::SimParams params = sim::preset(o.preset);
  if (o.frames > 0) sim::resize(params, params.width, params.height, o.frames);
  SubProgress simProgress(progress, 0.0, 0.25);
  sim::SimResult sim = sim::simulate(params, o.seed, simProgress, cancel);
  io::writeCube(path("observation.fits"), sim.cube, io::provenanceCards("simulate " + o.preset));
  sim::writeTruth(path("observation.truth.json"), sim.truth);
  progress.finish();
  timings.mark("simulated and written");
  const double simulatedAt = timings.elapsed();

  // 2. Pre-processing (the raw cube becomes the zero-biased cube in place).
  // On the search's device when it is a GPU (per-pixel background and matched filter, issue 16).
  BackendSelection& backend = backendMade.get();
  timings.mark("backend ready");
  std::string accelMessage;
  const auto accel = makePreprocessAccelerator(*backend.backend, accelMessage);
  pipeline::PreprocessParams prepParams;
  prepParams.accelerator = accel.get();
  SubProgress prepProgress(progress, 0.25, 0.5);
  pipeline::Prepared prepared = pipeline::preprocess(std::move(sim.cube), prepParams, prepProgress, cancel);
  progress.finish();
  timings.stages(prepared.stageSeconds);
  timings.mark("pre-processed");
  pipeline::writePreparedSidecar(path("prepared.json"), prepared);
  for (const auto& note : prepared.notes)
    if (note.rfind("warning:", 0) == 0) std::fprintf(stderr, "%s\n", note.c_str());

  // 3. The velocity search, +-vmax deg/day around the sky rate.
  SubProgress searchProgress(progress, 0.5, 0.9);
  const search::SearchResult result = demoSearch(o, prepared, *backend.backend, searchProgress, cancel);
  progress.finish();
  timings.mark("searched");
  std::fputs(searchNotesText(result).c_str(), stderr);
  nlohmann::json report = report::searchResultToJson(prepared.filtered, result, {path("observation.fits")});

  // 4. Co-moving fits and segment checks of the best candidates.
  const int nFits = std::min<int>(o.fits, static_cast<int>(result.candidates.size()));
  std::vector<std::optional<candidate::FitSummary>> fits(result.candidates.size());  // typed; JSON only written
  for (int i = 0; i < nFits; ++i) {
    progress.report(0.9 + 0.1 * i / std::max(1, nFits), "co-moving fits");
    fits[i] = candidate::fitCandidate(prepared, result.candidates[i], cancel);
    report["candidates"][i]["fit"] = report::toFlatJson(*fits[i]);
  }
  progress.finish();
  timings.mark("candidates fitted");
  report::writeJsonFile(path("candidates.json"), report);
  report::writeCandidatesCsv(path("candidates.csv"), report);
  writeStack(o.out / "stack_sky.fits", prepared.frames, prepared.skyRate, "tracking the sky");
  if (!result.candidates.empty()) {
    writeStack(o.out / "stack_candidate1.fits", prepared.frames, result.candidates.front().v,
               "tracking candidate 1");
  }
  timings.mark("outputs written");
  timings.line("after the simulation", timings.elapsed() - simulatedAt);

  // 5. What was found, against the truth.
  std::printf("synthtrack demo: %s, %zu frames of %dx%d, seed %llu\n", o.preset.c_str(),
              prepared.frames.frameCount(), prepared.frames.width(), prepared.frames.height(),
              static_cast<unsigned long long>(o.seed));
  std::printf(
      "  pre-processing: sigma_n %.3f, PSF FWHM %.2f px (%s), sky rate (%.3f, %.3f) px/s, %zu stars, "
      "%zu cosmic-ray pixels, %.1f s (%s)\n",
      prepared.sigmaN, prepared.psf.fwhm(), prepared.psfFitted ? "fitted" : "fallback", prepared.skyRate.vx,
      prepared.skyRate.vy, prepared.stars.size(), prepared.cosmicRays, prepared.elapsedS, accelMessage.c_str());
  std::printf(
      "  search: %s, method %s (%s), %d x %d velocities, step %.4f px/s, threshold SNR %.2f, %zu candidates, "
      "%.1f s\n",
      backend.message.c_str(), std::string(result.method.name()).c_str(), result.methodReason.c_str(),
      result.grid.nvx,
      result.grid.nvy, result.grid.stepPxS, result.snrThreshold, result.candidates.size(), result.elapsedS);
  int found = 0;
  for (const auto& t : sim.truth.objects) {
    const auto match = matchTruth(result.candidates, t, result.grid.stepPxS);
    if (match) ++found;
    std::printf("  truth %s: x %.1f y %.1f v (%.3f, %.3f) px/s, %.2f deg/day, expected SNR %.1f -> %s",
                t.name.c_str(), t.xRefPx, t.yRefPx, t.vxPxPerS, t.vyPxPerS, t.rateDegPerDay, t.expectedSnr,
                match ? "FOUND" : "not found");
    if (match) {
      const search::Candidate& c = result.candidates[*match];
      std::printf(" at x %d y %d, search SNR %.1f", c.x, c.y, c.snr);
      if (const auto& f = fits[*match]; f && f->converged()) {
        std::printf(", fit x %.2f y %.2f, SNR %.1f", f->x, f->y, f->snr);
        if (f->sky) std::printf(", %.2f deg/day", f->sky->rateDegPerDay);
      }
    }
    std::printf("\n");
  }
  std::printf("outputs in %s:\n", std::filesystem::absolute(o.out).c_str());
  for (const char* f : {"observation.fits", "observation.truth.json", "prepared.json", "candidates.json",
                        "candidates.csv", "stack_sky.fits", "stack_candidate1.fits"}) {
    if (std::filesystem::exists(o.out / f)) std::printf("  %s\n", f);
  }
  return found == static_cast<int>(sim.truth.objects.size()) ? 0 : 1;
}

}  // namespace st::app

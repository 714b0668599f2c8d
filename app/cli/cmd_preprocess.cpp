// synthtrack-cli preprocess INPUT... [--bias F]... [--flat F]... [--dark F]... [--sky-rate-px-s VX,VY]
//   -o prepared.fits: calibration, cosmic rays, background, static sources, PSF and matched filter (paper
//   §4.2-4.3); writes the zero-biased cube and a JSON sidecar (prepared.json) with noise, PSF, sky rate and
//   the star catalog.
#include <cstdio>
#include <filesystem>
#include <optional>
#include <string>

#include "cli_args.hpp"
#include "commands.hpp"
#include "observation_pipeline.hpp"
#include "plate_solve_args.hpp"
#include "st/pipeline/plate_solve_stage.hpp"
#include "load_args.hpp"
#include "st/calib/calibration.hpp"
#include "st/common/error.hpp"
#include "st/io/fits_reader.hpp"
#include "st/io/fits_writer.hpp"
#include "st/pipeline/prepared_cube.hpp"
#include "st/pipeline/prepared_json.hpp"
#include "st/pipeline/preprocess.hpp"
#include "terminal_progress.hpp"
#include "st/common/memory_budget.hpp"
#include "st/common/parallel.hpp"
#include "st/pipeline/memory_plan.hpp"

namespace st::app {
namespace {

std::pair<double, double> pairOf(const CliArgs& cli, const std::string& name) {
  const std::string v = *cli.value(name);
  const auto comma = v.find(',');
  try {
    if (comma == std::string::npos) throw std::invalid_argument(v);
    std::size_t used = 0;
    const double a = std::stod(v.substr(0, comma), &used);
    const std::string rest = v.substr(comma + 1);
    const double b = std::stod(rest, &used);
    if (used != rest.size()) throw std::invalid_argument(v);
    return {a, b};
  } catch (const std::exception&) {
    throw UsageError("--" + name + " needs two numbers as A,B, got '" + v + "'");
  }
}

const char* kHelp =
    "usage: synthtrack-cli preprocess INPUT... -o PREPARED.fits [options]\n\n"
    "Calibrates (overscan BIASSEC, bias, dark, flat, TRIMSEC), removes cosmic rays, estimates the "
    "background\n"
    "and noise (paper §3.1), finds and zeroes static sources at the sky rate, fits the PSF and writes the\n"
    "zero-biased cube (background subtracted, NOT matched-filtered) plus PREPARED.json (noise, PSF, sky\n"
    "rate, star catalog). Its header says what it is (STPREP = 1, STFILT = F, PSFFWHM, PSFBETA, SIGMAN,\n"
    "SKYVX/SKYVY): `search PREPARED.fits --preprocessed` matched-filters it with that PSF before "
    "searching.\n\n"
    "  -o PREPARED.fits        output cube (overwritten); the sidecar gets the .json extension\n"
    "  --bias F / --flat F / --dark F   calibration frames (files or folders; repeat for several)\n"
    "  --sky-rate-px-s VX,VY   motion of the stars, px/s (default: measured from the stars)\n"
    "  --fwhm PX               PSF FWHM when no star is usable for the fit (default 3)\n"
    "  --psf-star X,Y          fit the PSF on the star at this 0-based pixel (t_ref)\n"
    "  --filtered F.fits       also write the matched-filtered cube (STFILT = T, SIGMAF; searched as is)\n"
    "  --background F.fits     also write the background image that was subtracted\n"
    "  --no-cosmic-rays        skip cosmic-ray removal\n"
    "  --no-register           no per-frame registration: the linear sky rate is the model even when the\n"
    "                          star field jumps (by default the star field is followed from frame to frame;\n"
    "                          per-frame offsets, when dithers, guiding or re-pointing need them, are written\n"
    "                          to the output's FRAMES table as REGX_PX/REGY_PX and used by search and stack)\n"
    "  --register              per-frame registration (the default; kept for scripts)\n"
    "  --memory-limit SIZE     memory budget, e.g. 8G or 500M (default: 70% of the memory available now,\n"
    "                          within the cgroup's limit); the peak is estimated and printed first, and an\n"
    "                          input that does not fit stops with exit 1 before any pixel is read\n"
    "  (with --crop, the calibration frames are cropped alike)\n"
    "  --plate-solve           when the frames have no WCS, plate-solve the first frame with astrometry.net\n"
    "                          (the pre-processed star catalogue when that fails; options below) and carry\n"
    "                          the WCS into every output, so that RA/Dec, the compass and ADES work\n"
    "  --json                  print the sidecar to stdout as well\n";

}  // namespace

int cmdPreprocess(const Args& args) {
  if (!args.empty() && args[0] == "--help") {
    std::printf("%s%s%s%s", kHelp, calibOptionsHelp(), loadOptionsHelp(), plateSolveOptionsHelp());
    return 0;
  }
  auto names = loadOptionNames();
  for (const char* n :
       {"o", "bias", "flat", "dark", "sky-rate-px-s", "fwhm", "psf-star", "filtered", "background",
        "memory-limit"})
    names.insert(n);
  for (const auto& n : plateSolveOptionNames())
    names.insert(n);
  auto flags = calibFlagNames();
  flags.insert({"no-cosmic-rays", "register", "no-register", "json", "plate-solve"});
  for (const auto& f : plateSolveFlagNames())
    flags.insert(f);
  const CliArgs cli(args, names, flags);
  if (cli.positionals().empty()) throw UsageError("give at least one INPUT (a FITS file or a folder)");
  const auto out = cli.value("o");
  if (!out) throw UsageError("give the output file with -o PREPARED.fits");
  pipeline::PreprocessParams params;
  params.calib = calibParamsFromArgs(cli);
  if (cli.has("sky-rate-px-s")) {
    const auto [vx, vy] = pairOf(cli, "sky-rate-px-s");
    params.skyRate = Velocity{vx, vy};
  }
  if (cli.has("psf-star")) params.psfStar = pairOf(cli, "psf-star");
  params.psfFwhmPx = cli.number("fwhm", 3.0);
  if (!(params.psfFwhmPx > 0.5 && params.psfFwhmPx < 100.0))
    throw UsageError("--fwhm must be in (0.5, 100) px");
  params.removeCosmicRays = !cli.flag("no-cosmic-rays");
  params.registerFrames = !cli.flag("no-register");
  params.matchedFilter = cli.has("filtered");

  TerminalProgress progress;
  CancelToken& cancel = processCancelToken();
  FrameCube cube;
  const io::LoadOptions loadOptions = loadOptionsFromArgs(cli);
  {
    // The memory plan before any pixel is read (issue 20).
    const MemoryBudget budget = resolveMemoryBudget(cli.value("memory-limit"));
    const io::InputSummary summary = io::summarizeInputs(cli.positionals(), loadOptions);
    const pipeline::CubeShape shape{summary.width, summary.height, summary.frames};
    const MemoryEstimate need = pipeline::estimatePreprocessPeak(shape, params.matchedFilter, workerCount());
    std::fprintf(stderr, "memory: budget %s (%s)\nmemory: pre-processing in memory: estimated peak %s\n",
                 formatBytes(static_cast<double>(budget.bytes)).c_str(), budget.source.c_str(),
                 need.describe().c_str());
    if (need.total() > static_cast<double>(budget.bytes)) {
      throw InputError(pipeline::overBudgetMessage(std::to_string(shape.frames) + " frames of " +
                                                       std::to_string(shape.width) + " x " +
                                                       std::to_string(shape.height) +
                                                       " px: pre-processing in memory (`preprocess` writes the "
                                                       "whole zero-biased cube; `search --keep-scratch` "
                                                       "pre-processes out of core and keeps the filtered cube)",
                                                   need, budget));
    }
  }
  {
    SubProgress sub(progress, 0.0, 0.2);
    cube = io::loadFrames(cli.positionals(), loadOptions, sub, cancel);
  }
  // --plate-solve: the first raw frame first (its sources' core positions are the more precise: Lowell 42"
  // 0.63 arcsec from the header WCS at the centre, the stack catalogue's flux-weighted centroids 1.08), the
  // WCS then carried through calibration like a header's; the pre-processed star catalogue when that fails.
  bool plateSolveFromStars = false;
  std::string plateSolveNote;
  if (cli.flag("plate-solve")) {
    if (cube.wcs) {
      plateSolveNote = "the frames have a WCS: not plate-solved";
    } else {
      try {
        SubProgress sub(progress, 0.2, 0.22);
        const astro::PlateSolution s = pipeline::plateSolveRawCube(cube, plateSolveParamsFromArgs(cli), sub, cancel);
        plateSolveNote = "WCS of the first frame " + pipeline::describeSolution(s);
      } catch (const InputError& e) {
        std::fprintf(stderr, "note: plate solving the first frame: %s; trying the star catalogue after "
                             "pre-processing\n", e.what());
        plateSolveFromStars = true;
      }
    }
  }
  pipeline::checkNotPrepared(cube, "search it with `synthtrack-cli search " + pipeline::cubeSource(cube) +
                                       " --preprocessed`, or pre-process the raw frames");
  std::vector<std::string> warnings = cube.warnings;
  const FrameCube bias =
      loadCalibrationFrames(cli.values("bias"), loadOptions.crop, progress, processCancelToken());
  const FrameCube dark =
      loadCalibrationFrames(cli.values("dark"), loadOptions.crop, progress, processCancelToken());
  const FrameCube flat =
      loadCalibrationFrames(cli.values("flat"), loadOptions.crop, progress, processCancelToken());
  for (const FrameCube* c : {&bias, &dark, &flat})
    warnings.insert(warnings.end(), c->warnings.begin(), c->warnings.end());
  if (!bias.empty() || !dark.empty() || !flat.empty()) {
    params.masters = calib::buildMasters(bias, dark, flat, cube, params.calib, progress, cancel);
    warnings.insert(warnings.end(), params.masters->warnings.begin(), params.masters->warnings.end());
  }
  pipeline::Prepared prepared;
  {
    SubProgress sub(progress, 0.2, 0.95);
    prepared = pipeline::preprocess(std::move(cube), params, sub, cancel);
  }
  if (plateSolveFromStars) {
    SubProgress sub(progress, 0.95, 0.99);
    pipeline::plateSolvePrepared(prepared, plateSolveParamsFromArgs(cli), sub, cancel);
  }
  if (!plateSolveNote.empty()) prepared.notes.push_back(plateSolveNote);
  using pipeline::PreparedState;
  io::writeCube(*out, prepared.frames, pipeline::preparedCubeCards(prepared, PreparedState::ZeroBiased));
  if (params.matchedFilter) {
    io::writeCube(*cli.value("filtered"), prepared.filtered.frames,
                  pipeline::preparedCubeCards(prepared, PreparedState::Filtered));
  }
  if (cli.has("background")) {
    io::writeImage(*cli.value("background"), prepared.background,
                   pipeline::preparedCubeCards(prepared, std::nullopt));
  }
  const std::string sidecar = pipeline::preparedSidecarPath(*out);
  pipeline::writePreparedSidecar(sidecar, prepared);
  progress.finish();
  warnings.insert(warnings.end(), prepared.calibration.warnings.begin(), prepared.calibration.warnings.end());
  printWarnings(warnings);
  for (const auto& n : prepared.notes)
    std::fprintf(stderr, "note: %s\n", n.c_str());
  if (cli.flag("json")) {
    std::printf("%s\n", pipeline::preparedToJson(prepared).dump(2).c_str());
    return 0;
  }
  std::printf("wrote %s and %s: %zu frames of %d x %d px\n", out->c_str(), sidecar.c_str(),
              prepared.frames.frameCount(), prepared.frames.width(), prepared.frames.height());
  std::printf("sigma_n %.4g counts, background %.6g counts, sky rate (%.4g, %.4g) px/s%s\n", prepared.sigmaN,
              prepared.global.mean, prepared.skyRate.vx, prepared.skyRate.vy,
              prepared.skyRateMeasured ? " (measured)" : "");
  std::printf("%zu stars, %zu cosmic-ray pixels, PSF FWHM %.3g px (%s), %.1f s\n", prepared.stars.size(),
              prepared.cosmicRays, prepared.psf.fwhm(), prepared.psfFitted ? "fitted" : "given",
              prepared.elapsedS);
  return 0;
}

}  // namespace st::app

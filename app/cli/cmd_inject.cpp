// synthtrack-cli inject INPUT... -o DIR: copies of the raw frames with synthetic movers added, and
// DIR/truth.json (core/inject: st::inject::injectIntoFiles). Injection-recovery as survey pipelines
// validate themselves (ARCHITECTURE.md, "Validation beyond the simulator").
#include <cstdio>
#include <filesystem>
#include <string>
#include <tuple>

#include "cli_args.hpp"
#include "commands.hpp"
#include "observation_pipeline.hpp"
#include "load_args.hpp"
#include "st/calib/calibration.hpp"
#include "st/common/units.hpp"
#include "st/inject/injection.hpp"
#include "st/inject/truth_json.hpp"
#include "st/io/fits_reader.hpp"
#include "st/report/search_report.hpp"
#include "terminal_progress.hpp"

namespace st::app {
namespace {

constexpr const char* kHelp =
    "usage: synthtrack-cli inject INPUT... -o DIR --rate A,B --seed S [options]\n\n"
    "Writes copies of the RAW frames INPUT into DIR with synthetic movers added, and DIR/truth.json.\n"
    "Same file names and HDU numbers, headers untouched apart from HISTORY and STINJECT (number of movers)\n"
    "and a refreshed CHECKSUM; tile-compressed .fz (and .gz) inputs are written uncompressed, at the same\n"
    "HDU number, under the name without .fz/.gz. Each mover is the field's Moffat PSF trailed over each\n"
    "exposure, linear in time from (x, y) at t_ref, away from stars and inside the frame over the whole\n"
    "span, with the flux that gives the requested expected SNR (optimal matched filter of the whole track\n"
    "against the local frame-to-frame noise), Poisson noise at the gain, and times the normalised flat in\n"
    "raw counts. Positions in truth.json are 0-based pixels of the calibrated (trimmed) frame, as 'search'\n"
    "reports them. Calibrate, pre-process and search the copies as the originals, then run 'recovery'.\n\n"
    "  -o DIR                 output folder (created; files in it are overwritten)\n"
    "  --n N                  number of movers (default 40)\n"
    "  --snr A,B              expected SNR, uniform in [A, B] (default 4,20)\n"
    "  --rate A,B             speed in the frames, uniform in [A, B]; direction uniform\n"
    "  --rate-unit px-s|deg-day   unit of --rate (default px-s; deg-day needs a plate scale: WCS or\n"
    "                         --plate-scale)\n"
    "  --seed S               random seed: the same inputs and seed give the same movers\n"
    "  --fwhm PX [--beta B]   the PSF (Moffat, beta default 4) instead of fitting stars of the frames\n"
    "  --gain E_PER_ADU       gain for the Poisson noise (default: the GAIN or EGAIN keyword)\n"
    "  --bias F / --flat F / --dark F   calibration frames, as for 'preprocess' (repeat or give folders)\n"
    "  --min-star-distance PX track to the nearest star/bad pixel of the median frame (default max(5, 3 "
    "FWHM))\n"
    "  --edge-margin PX       track to the frame edge (default max(10, 3 FWHM))\n"
    "  --min-separation PX    between movers at the same time (default max(10, 5 FWHM))\n"
    "  --star-sigma K         star pixels: median frame above its background + K sigma (default 5)\n"
    "  --zero-point MAG       magnitude of 1 calibrated count/s, for the movers' magnitudes (default none)\n"
    "  --json                 print truth.json to stdout as well\n";

std::pair<double, double> pairOf(const CliArgs& cli, const std::string& name,
                                 std::pair<double, double> fallback) {
  const auto v = cli.value(name);
  if (!v) return fallback;
  double a = 0.0, b = 0.0;
  char comma = 0, extra = 0;
  if (std::sscanf(v->c_str(), "%lf%c%lf%c", &a, &comma, &b, &extra) != 3 || comma != ',')
    throw UsageError("--" + name + " needs two numbers as A,B, got '" + *v + "'");
  return {a, b};
}

}  // namespace

int cmdInject(const Args& args) {
  auto names = loadOptionNames();
  for (const char* n :
       {"o", "n", "snr", "rate", "rate-unit", "seed", "fwhm", "beta", "gain", "bias", "flat", "dark",
        "min-star-distance", "edge-margin", "min-separation", "star-sigma", "zero-point"})
    names.insert(n);
  const CliArgs cli(args, names, {"json", "help"});
  if (cli.flag("help")) {
    std::printf("%s%s", kHelp, loadOptionsHelp());
    return 0;
  }
  if (cli.positionals().empty()) throw UsageError("give at least one INPUT (raw FITS files or a folder)");
  const auto outDir = cli.value("o");
  if (!outDir) throw UsageError("give the output folder with -o DIR");
  if (!cli.has("rate")) throw UsageError("give the speed range with --rate A,B");
  const auto seed = cli.integer("seed");
  if (!seed || *seed < 0) throw UsageError("give a random seed >= 0 with --seed S");
  const std::string unit = cli.value("rate-unit").value_or("px-s");
  if (unit != "px-s" && unit != "deg-day")
    throw UsageError("--rate-unit must be px-s or deg-day, got '" + unit + "'");
  if (cli.has("beta") && !cli.has("fwhm")) throw UsageError("--beta goes with --fwhm");
  if (cli.has("dark") && !cli.has("bias")) throw UsageError("--dark needs --bias");
  if (cli.has("crop")) throw UsageError("inject writes whole raw frames: --crop is not supported");

  inject::InjectParams p;
  p.count = static_cast<int>(cli.integer("n").value_or(40));
  std::tie(p.snrMin, p.snrMax) = pairOf(cli, "snr", {4.0, 20.0});
  const auto [rateA, rateB] = pairOf(cli, "rate", {0.0, 0.0});
  p.seed = static_cast<std::uint64_t>(*seed);
  p.minStarDistancePx = cli.number("min-star-distance", 0.0);
  p.edgeMarginPx = cli.number("edge-margin", 0.0);
  p.minSeparationPx = cli.number("min-separation", 0.0);
  p.zeroPointMag = cli.number("zero-point");
  inject::FieldParams fp;
  fp.starThresholdSigma = cli.number("star-sigma", 5.0);
  if (auto w = cli.number("fwhm")) {
    const double beta = cli.number("beta", 4.0);
    if (!(*w > 0.5 && *w < 100.0)) throw UsageError("--fwhm must be in (0.5, 100) px");
    if (!(beta > 1.0)) throw UsageError("--beta must be > 1");
    fp.psf = psf::Moffat::fromFwhm(*w, beta);
  }

  TerminalProgress progress;
  CancelToken& cancel = processCancelToken();
  FrameCube raw;
  {
    SubProgress sub(progress, 0.0, 0.1);
    raw = io::loadFrames(cli.positionals(), loadOptionsFromArgs(cli), sub, cancel);
  }
  inject::TruthMeta meta;
  meta.rateUnit = unit;
  meta.rateMinAsked = rateA;
  meta.rateMaxAsked = rateB;
  meta.plateScaleArcsecPerPx = raw.plateScaleArcsecPerPx;
  if (unit == "deg-day") {
    if (!meta.plateScaleArcsecPerPx)
      throw UsageError("--rate-unit deg-day needs a plate scale: the frames have no WCS; give --plate-scale");
    p.rateMinPxS = degPerDayToPxPerSec(rateA, *meta.plateScaleArcsecPerPx);
    p.rateMaxPxS = degPerDayToPxPerSec(rateB, *meta.plateScaleArcsecPerPx);
  } else {
    p.rateMinPxS = rateA;
    p.rateMaxPxS = rateB;
  }
  double gain = 0.0;
  if (auto g = cli.number("gain")) {
    gain = *g;
    meta.gainSource = "--gain";
  } else if (auto hg = raw.header.getDouble("GAIN")) {
    gain = *hg;
    meta.gainSource = "GAIN keyword";
  } else if (auto he = raw.header.getDouble("EGAIN")) {
    gain = *he;
    meta.gainSource = "EGAIN keyword";
  } else {
    throw UsageError("the frames have no GAIN (or EGAIN) keyword: give the gain in e-/ADU with --gain");
  }
  if (!(gain > 0.0)) throw UsageError("the gain must be > 0 e-/ADU, got " + std::to_string(gain));
  meta.biasFiles = cli.values("bias");
  meta.flatFiles = cli.values("flat");
  const calib::CalibParams calibParams;
  calib::MasterCalibration masters;
  {
    SubProgress sub(progress, 0.1, 0.2);
    const FrameCube bias = loadCalibrationFrames(cli.values("bias"), std::nullopt, sub, cancel);
    const FrameCube dark = loadCalibrationFrames(cli.values("dark"), std::nullopt, sub, cancel);
    const FrameCube flat = loadCalibrationFrames(cli.values("flat"), std::nullopt, sub, cancel);
    if (!bias.empty() || !flat.empty())
      masters = calib::buildMasters(bias, dark, flat, raw, calibParams, sub, cancel);
  }
  const std::vector<std::string> warnings = raw.warnings;
  inject::InjectionRun run;
  {
    SubProgress sub(progress, 0.2, 1.0);
    run = inject::injectIntoFiles(std::move(raw), masters, calibParams, fp, p, gain, *outDir, sub, cancel);
  }
  const nlohmann::json truth = inject::truthToJson(run, meta);
  const std::string truthPath = (std::filesystem::path(*outDir) / "truth.json").string();
  report::writeJsonFile(truthPath, truth);
  progress.finish();
  for (const auto& w : warnings)
    std::fprintf(stderr, "warning: %s\n", w.c_str());
  if (run.clippedPixels > 0)
    std::fprintf(stderr, "warning: %zu pixels reached the raw type's limit and were clipped\n",
                 run.clippedPixels);
  if (cli.flag("json")) {
    std::printf("%s\n", truth.dump(2).c_str());
    return 0;
  }
  const auto& plan = run.plan;
  std::printf("wrote %zu files and %s: %zu movers, seed %llu, t_ref MJD %.8f\n", run.written.size(),
              truthPath.c_str(), plan.objects.size(), static_cast<unsigned long long>(plan.params.seed),
              plan.tRefMjd);
  std::printf(
      "PSF %s: Moffat FWHM %.3f px, beta %.3f (stamp radius %.1f px); gain %.4g e-/ADU (%s); %zu star/bad "
      "pixels masked\n",
      plan.psfMeasured ? "measured" : "given", plan.psf.fwhm(), plan.psf.beta, plan.stampRadiusPx, gain,
      meta.gainSource.c_str(), run.field.maskedPixels);
  std::printf("%4s %9s %9s %12s %12s %11s %8s\n", "id", "x_px", "y_px", "vx_px_s", "vy_px_s", "flux",
              "exp_snr");
  for (const auto& o : plan.objects)
    std::printf("%4d %9.2f %9.2f %12.6f %12.6f %11.1f %8.2f\n", o.id, o.xPx, o.yPx, o.vxPxS, o.vyPxS, o.flux,
                o.expectedSnr);
  return 0;
}

}  // namespace st::app

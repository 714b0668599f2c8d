// synthtrack-cli simulate: writes a synthetic observation (FITS cube + truth JSON), optionally with raw
// calibration frames, from a simulator preset (core/sim).
#include <cstdio>
#include <filesystem>
#include <string>
#include <tuple>

#include "cli_args.hpp"
#include "commands.hpp"
#include "st/common/error.hpp"
#include "st/io/fits_writer.hpp"
#include "st/sim/simulator.hpp"
#include "terminal_progress.hpp"

namespace st::app {

namespace {

constexpr const char* kUsage =
    "usage: synthtrack-cli simulate --preset NAME [--seed N] [--frames N] [--size WxH] [--noiseless]\n"
    "                               [--calib-dir DIR [--calib-frames N]] -o OUT.fits\n"
    "  Writes OUT.fits (3-D float32 cube of raw ADU frames, FRAMES time table, TAN WCS) and\n"
    "  OUT.truth.json (what was simulated: PSF, noise, sky rate, objects with expected SNR, stars, cosmic\n"
    "  rays, hot pixels). Presets: paper-neo (the paper's 23 mag NEA, 512x512x500), known-pair (2 Hz,\n"
    "  960 frames, 16 mag star + 18.5 mag asteroid), small (128x128x64, for tests).\n"
    "  --seed N          random seed (default 1); the same seed gives identical files\n"
    "  --frames N        number of frames instead of the preset's\n"
    "  --size WxH        frame size instead of the preset's (objects keep their place relative to the "
    "centre)\n"
    "  --noiseless       expected values only (no photon, EM or read noise)\n"
    "  --calib-dir DIR   also write N raw bias frames bias_NN.fits and N raw flats flat_NN.fits there, plus\n"
    "                    the exact patterns used, truth_bias.fits and truth_flat.fits\n"
    "  --calib-frames N  number of bias and of flat frames (default 5)\n";

std::pair<int, int> parseSize(const std::string& text) {
  const auto x = text.find_first_of("xX");
  try {
    if (x == std::string::npos) throw std::invalid_argument(text);
    std::size_t used1 = 0, used2 = 0;
    const int w = std::stoi(text.substr(0, x), &used1);
    const int h = std::stoi(text.substr(x + 1), &used2);
    if (used1 != x || used2 != text.size() - x - 1 || w <= 0 || h <= 0) throw std::invalid_argument(text);
    return {w, h};
  } catch (const std::exception&) {
    throw UsageError("option --size needs WIDTHxHEIGHT in pixels, e.g. 256x256, got '" + text + "'");
  }
}

// OUT.fits -> OUT.truth.json (strips .fits, .fit, .fts, with an optional .gz/.fz).
std::string truthPathFor(const std::string& out) {
  std::string base = out;
  for (const char* ext : {".gz", ".fz"}) {
    if (base.size() > 3 && base.compare(base.size() - 3, 3, ext) == 0) base.resize(base.size() - 3);
  }
  for (const char* ext : {".fits", ".fit", ".fts"}) {
    const std::string e = ext;
    if (base.size() > e.size() && base.compare(base.size() - e.size(), e.size(), e) == 0) {
      base.resize(base.size() - e.size());
      break;
    }
  }
  return base + ".truth.json";
}

FitsHeader calibHeader(const sim::SimParams& p, const char* type, double exposureS) {
  FitsHeader h;
  h.setString("IMAGETYP", type, "simulated calibration frame");
  h.setNumber("EXPTIME", exposureS, "[s]");
  h.setNumber("GAIN", p.gainEPerAdu, "[e-/ADU]");
  h.setNumber("RDNOISE", p.readNoiseE, "[e-]");
  h.setString("SIMPRSET", p.presetName);
  return h;
}

void writeCalibration(const std::string& dir, const sim::SimParams& p, std::uint64_t seed, int count,
                      const sim::SimResult& result) {
  std::filesystem::create_directories(dir);
  const auto cal = sim::simulateCalibrationFrames(p, seed, count, count);
  char name[64];
  for (int k = 0; k < count; ++k) {
    std::snprintf(name, sizeof name, "bias_%02d.fits", k + 1);
    io::writeImage((std::filesystem::path(dir) / name).string(), cal.bias[k], calibHeader(p, "BIAS", 0.0));
    std::snprintf(name, sizeof name, "flat_%02d.fits", k + 1);
    io::writeImage((std::filesystem::path(dir) / name).string(), cal.flat[k], calibHeader(p, "FLAT", 1.0));
  }
  io::writeImage((std::filesystem::path(dir) / "truth_bias.fits").string(), result.biasFrame,
                 calibHeader(p, "BIAS", 0.0));
  io::writeImage((std::filesystem::path(dir) / "truth_flat.fits").string(), result.flatFrame,
                 calibHeader(p, "FLAT", 0.0));
}

}  // namespace

int cmdSimulate(const Args& args) {
  if (!args.empty() && (args[0] == "--help" || args[0] == "-h")) {
    std::fputs(kUsage, stdout);
    return 0;
  }
  const CliArgs cli(args, {"preset", "seed", "frames", "size", "o", "calib-dir", "calib-frames"},
                    {"noiseless"});
  if (!cli.positionals().empty()) throw UsageError("unexpected argument '" + cli.positionals().front() + "'");
  const auto presetName = cli.value("preset");
  if (!presetName) throw UsageError("--preset NAME is required (paper-neo, known-pair, small)");
  const auto out = cli.value("o");
  if (!out) throw UsageError("-o OUT.fits is required");
  const long long seed = cli.integer("seed").value_or(1);
  if (seed < 0) throw UsageError("option --seed needs a non-negative integer, got " + std::to_string(seed));
  const long long frames = cli.integer("frames").value_or(0);
  if (cli.has("frames") && (frames <= 0 || frames > 1000000)) {
    throw UsageError("option --frames needs 1..1000000, got " + std::to_string(frames));
  }
  const long long calibFrames = cli.integer("calib-frames").value_or(5);
  if (calibFrames < 1 || calibFrames > 99) {
    throw UsageError("option --calib-frames needs 1..99, got " + std::to_string(calibFrames));
  }
  if (cli.has("calib-frames") && !cli.has("calib-dir")) throw UsageError("--calib-frames needs --calib-dir");

  // Fail before the (long) simulation when the output cannot be written.
  const auto outDir = std::filesystem::path(*out).parent_path();
  if (!outDir.empty() && !std::filesystem::is_directory(outDir)) {
    throw InputError("output folder '" + outDir.string() + "' does not exist (for -o " + *out + ")");
  }
  sim::SimParams params = sim::preset(*presetName);
  int width = 0, height = 0;
  if (const auto size = cli.value("size")) std::tie(width, height) = parseSize(*size);
  sim::resize(params, width, height, static_cast<int>(frames));
  params.noiseless = cli.flag("noiseless");

  TerminalProgress progress;
  const auto result = sim::simulate(params, static_cast<std::uint64_t>(seed), progress, processCancelToken());
  progress.report(1.0, "writing FITS");
  FitsHeader extra = io::provenanceCards("simulate");
  io::writeCube(*out, result.cube, extra);
  const std::string truthPath = truthPathFor(*out);
  sim::writeTruth(truthPath, result.truth);
  std::string calibDir;
  if (const auto dir = cli.value("calib-dir")) {
    writeCalibration(*dir, params, static_cast<std::uint64_t>(seed), static_cast<int>(calibFrames), result);
    calibDir = *dir;
  }
  progress.finish();

  std::printf("simulated %s (seed %lld): %d x %d px, %d frames at %.4g Hz\n", params.presetName.c_str(), seed,
              params.width, params.height, params.frames, params.frameRateHz);
  for (const auto& o : result.truth.objects) {
    std::printf(
        "  object %s: x %.2f y %.2f px at t_ref, v (%.4f, %.4f) px/s, %.2f deg/day vs stars, V %.2f, "
        "expected SNR %.2f (star-tracking stack %.2f)\n",
        o.name.c_str(), o.xRefPx, o.yRefPx, o.vxPxPerS, o.vyPxPerS, o.rateDegPerDay, o.magnitude,
        o.expectedSnr, o.skyStackSnr);
  }
  std::printf("cube:  %s\ntruth: %s\n", out->c_str(), truthPath.c_str());
  if (!calibDir.empty()) std::printf("calibration frames: %s\n", calibDir.c_str());
  return 0;
}

}  // namespace st::app

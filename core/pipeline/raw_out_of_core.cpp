#include "st/pipeline/raw_out_of_core.hpp"

#include <unistd.h>

#include <algorithm>
#include <filesystem>

#include "st/common/error.hpp"
#include "st/pipeline/prepared_cube.hpp"

namespace st::pipeline {
namespace {

void appendOnce(std::vector<std::string>& to, const std::vector<std::string>& from) {
  for (const auto& w : from)
    if (std::find(to.begin(), to.end(), w) == to.end()) to.push_back(w);
}

/// Frames of `r` (image coordinates, i.e. inside the user's crop) read with CFITSIO's subset reader.
FrameCube loadRegion(const RawObservationFiles& files, const search::TileRect& r, CancelToken& cancel) {
  io::LoadOptions lo = files.load;
  const int bx = files.load.crop ? files.load.crop->x0 : 0, by = files.load.crop ? files.load.crop->y0 : 0;
  lo.crop = io::CropRegion{bx + r.x0, by + r.y0, r.width, r.height};
  NullProgress quiet;
  return io::loadFrames(files.inputs, lo, quiet, cancel);
}

std::string scratchPath(const RawObservationFiles& files, const RawOutOfCoreOptions& o) {
  std::filesystem::path first(files.inputs.front());
  if (first.filename().empty()) first = first.parent_path();  // a folder given as "science/"
  const std::filesystem::path stem = first.filename().replace_extension();
  // A kept cube has a name to find it by; a temporary one is the process's own (two runs in one folder, or
  // a cube kept before, are never overwritten or removed by another run).
  const std::string name = o.keepScratch ? stem.string() + ".synthtrack-filtered.fits"
                                         : stem.string() + ".synthtrack-filtered." + std::to_string(::getpid()) +
                                               ".fits";
  return (std::filesystem::path(o.scratchDir) / name).string();
}

}  // namespace

FrameCube loadCalibrationFrames(const std::vector<std::string>& files, const std::optional<io::CropRegion>& crop,
                                ProgressSink& progress, CancelToken& cancel) {
  if (files.empty()) return {};
  io::LoadOptions opt;  // calibration frames need no times: a nominal clock
  opt.startMjd = 0.0;
  opt.frameRateHz = 1.0;
  opt.scienceFrames = false;  // bias/dark/flat are expected here: no 'not a science frame' warning
  opt.crop = crop;
  return io::loadFrames(files, opt, progress, cancel);
}

RawOutOfCorePlan planRawOutOfCore(const RawObservationFiles& files, const io::InputSummary& summary,
                                  const RawOutOfCoreOptions& options, const MemoryBudget& budget,
                                  unsigned threads) {
  if (files.inputs.empty()) throw InputError("out-of-core pre-processing: no input files");
  RawOutOfCorePlan p;
  p.shape = {summary.width, summary.height, summary.frames};
  p.params.calib = files.calib;
  p.params.registerFrames = options.registerFrames;
  p.params.keepZeroBiased = false;
  const PreprocessHalo halo = preprocessHalo(p.params);
  const int overlap = halo.overlap();
  p.strips = planOutOfCorePreprocess(p.shape, budget.bytes, threads, overlap);
  if (p.strips.strips.empty()) {
    throw InputError(overBudgetMessage(
        std::to_string(p.shape.frames) + " frames of " + std::to_string(p.shape.width) + " x " +
            std::to_string(p.shape.height) + " px: pre-processing out of core (the smallest strip of rows, " +
            std::to_string(std::min(p.shape.height, kMinStripRows + 2 * overlap)) + " rows with the overlap)",
        p.strips.smallestStrip, budget));
  }
  p.description = "pre-processing out of core: " + std::to_string(p.strips.strips.size()) + " strips of up to " +
                  std::to_string(p.strips.strips.front().ownRows) + " rows (+" + std::to_string(overlap) +
                  " rows of overlap each side: " + halo.describe() + "), estimated peak " +
                  p.strips.perStrip.describe();
  p.path = scratchPath(files, options);
  p.trim = calib::trimRegion(summary.header, p.shape.width, p.shape.height, summary.files.front(), p.params.calib,
                             p.warnings);
  return p;
}

OutOfCorePrepared preprocessRawOutOfCore(const RawObservationFiles& files, const io::InputSummary& summary,
                                         const RawOutOfCorePlan& plan, ProgressSink& progress,
                                         CancelToken& cancel) {
  std::vector<std::string> warnings = plan.warnings;
  // The masters are built once for the whole frame (one normalised flat for every strip) and cropped to
  // each strip; the science frame they are checked against is the first frame's header and size.
  std::optional<calib::MasterCalibration> masters;
  {
    const FrameCube bias = loadCalibrationFrames(files.bias, files.load.crop, progress, cancel);
    const FrameCube dark = loadCalibrationFrames(files.dark, files.load.crop, progress, cancel);
    const FrameCube flat = loadCalibrationFrames(files.flat, files.load.crop, progress, cancel);
    if (!bias.empty() || !dark.empty() || !flat.empty()) {
      FrameCube science(plan.shape.width, plan.shape.height, 1);
      science.header = summary.header;
      science.info()[0].file = summary.files.front();
      masters = calib::buildMasters(bias, dark, flat, science, plan.params.calib, progress, cancel);
      appendOnce(warnings, masters->warnings);
    }
  }
  const RawRegionLoader load = [&](const search::TileRect& r) {
    RawRegion region;
    region.raw = loadRegion(files, r, cancel);
    // The strip's own crop clips the image sections (TRIMSEC ...) to it: said once for the frame instead.
    std::erase_if(region.raw.warnings,
                  [](const std::string& w) { return w.find("outside the crop") != std::string::npos; });
    checkNotPrepared(region.raw, "search it with --preprocessed");
    if (masters) region.masters = calib::cropMasters(*masters, {r.x0, r.y0, r.width, r.height});
    return region;
  };
  OutOfCorePrepared prepared =
      preprocessOutOfCore(load, plan.shape, plan.trim, plan.params, plan.strips, plan.path, progress, cancel);
  prepared.warnings.insert(prepared.warnings.begin(), warnings.begin(), warnings.end());
  return prepared;
}

}  // namespace st::pipeline

// injectIntoFiles: the whole `synthtrack-cli inject` after loading (st/inject/injection.hpp).
#include <filesystem>
#include <map>

#include "st/common/error.hpp"
#include "st/inject/injection.hpp"
#include "st/io/fits_copy.hpp"

namespace st::inject {

InjectionRun injectIntoFiles(FrameCube raw, const calib::MasterCalibration& masters,
                             const calib::CalibParams& calibParams, const FieldParams& fieldParams,
                             const InjectParams& params, double gainEPerAdu, const std::string& outDir,
                             ProgressSink& progress, CancelToken& cancel) {
  InjectionRun run;
  run.geometry = rawGeometry(raw, masters, calibParams);
  run.geometry.gainEPerAdu = gainEPerAdu;
  const std::vector<FrameInfo> info = raw.info();
  // One output per input file; frames of a 3-D cube share their file.
  std::vector<std::string> files;
  std::map<std::string, std::vector<std::size_t>> framesOf;
  std::map<std::string, std::string> nameOwner;
  for (std::size_t n = 0; n < info.size(); ++n) {
    const std::string& f = info[n].file;
    if (f.empty()) throw InputError("inject: frame " + std::to_string(n) + " was not read from a file");
    if (!framesOf.count(f)) {
      files.push_back(f);
      const std::string name = injectedFileName(f);
      if (auto [it, fresh] = nameOwner.emplace(name, f); !fresh)
        throw InputError("inject: inputs '" + it->second + "' and '" + f + "' would both be written as '" + name +
                         "'");
    }
    framesOf[f].push_back(n);
  }
  std::filesystem::create_directories(outDir);
  for (const auto& f : files) {
    const auto out = std::filesystem::path(outDir) / injectedFileName(f);
    std::error_code ec;
    if (std::filesystem::equivalent(out, f, ec))
      throw InputError("inject: '" + out.string() + "' is the input itself; choose another -o DIR");
  }
  {
    SubProgress sub(progress, 0.0, 0.1);
    calib::applyCalibration(raw, masters, calibParams, sub, cancel);
  }
  {
    SubProgress sub(progress, 0.1, 0.6);
    run.field = measureField(raw, fieldParams, sub, cancel);
  }
  progress.report(0.6, "inject: placing movers");
  run.plan = planInjection(raw, run.field, params, cancel);
  raw = FrameCube{};  // the calibrated cube is no longer needed: the copies are made from the files
  FitsHeader cards;
  cards.set("STINJECT", std::to_string(run.plan.objects.size()),
            "synthetic movers added by synthtrack inject, seed " + std::to_string(run.plan.params.seed));
  const std::vector<std::string> history = {
      "synthtrack inject: " + std::to_string(run.plan.objects.size()) + " synthetic movers added (seed " +
      std::to_string(run.plan.params.seed) + "), truth in truth.json"};
  for (std::size_t k = 0; k < files.size(); ++k) {
    cancel.throwIfCancelled();
    const std::string& f = files[k];
    std::vector<Image> signals;
    std::vector<io::PlaneAddition> additions;
    signals.reserve(framesOf[f].size());
    for (const std::size_t n : framesOf[f])
      signals.push_back(rawSignal(run.plan, n, run.geometry));
    for (std::size_t j = 0; j < framesOf[f].size(); ++j) {
      const FrameInfo& fi = info[framesOf[f][j]];
      additions.push_back({fi.hdu, fi.plane, &signals[j]});
    }
    const std::string out = (std::filesystem::path(outDir) / injectedFileName(f)).string();
    run.clippedPixels += io::copyWithAddedPixels(f, out, additions, cards, history).clippedPixels;
    run.inputs.push_back(f);
    run.written.push_back(out);
    progress.report(0.6 + 0.4 * static_cast<double>(k + 1) / files.size(), "inject: writing frames");
  }
  return run;
}

}  // namespace st::inject

#include "core_adapter.hpp"

#include <QDir>
#include <QFileInfo>
#include <QStandardPaths>
#include <algorithm>
#include <cmath>
#include <filesystem>

#include "backend_factory.hpp"
#include "fit_service.hpp"
#include "observation_pipeline.hpp"
#include "st/calib/calibration.hpp"
#include "st/common/error.hpp"
#include "st/io/fits_reader.hpp"
#include "st/io/fits_writer.hpp"
#include "st/io/wcs.hpp"
#include "st/common/parallel.hpp"
#include "st/pipeline/out_of_core_cube.hpp"
#include "st/psf/moffat_fit.hpp"
#include "st/session/preprocess_settings.hpp"
#include "st/sim/simulator.hpp"
#if __has_include("st/pipeline/preprocess.hpp")
#include "st/pipeline/prepared_cube.hpp"
#include "st/pipeline/prepared_json.hpp"
#include "st/pipeline/preprocess.hpp"
#define ST_GUI_HAVE_PIPELINE 1
#endif

namespace st::app {
namespace {

ui::ProfileFit profileAt(const Image& image, double x, double y) {
  ui::ProfileFit out;
  const psf::MoffatFit fit = psf::fitMoffat(image, x, y);
  out.centreX = fit.x0;
  out.centreY = fit.y0;
  out.fwhmPx = fit.fwhm();
  out.beta = fit.model.beta;
  const std::string implausible =
      fit.converged() ? psf::implausibleFit(fit, x, y, image.width, image.height) : std::string();
  out.ok = fit.converged() && implausible.empty();
  const double maxRadius = std::clamp(3.0 * (out.ok ? out.fwhmPx : 3.0), 6.0, 30.0);
  for (const psf::RadialBin& b : psf::radialProfile(image, fit, maxRadius)) {
    out.radiusPx.push_back(b.radius);
    out.value.push_back(b.mean);
    out.fitRadiusPx.push_back(b.radius);
    out.fitValue.push_back(b.model);
  }
  out.message =
      out.ok ? "± " + std::to_string(fit.sigmaFwhm).substr(0, 5) + " px, " + psf::toString(fit.convergence)
             : !implausible.empty() ? "Moffat fit rejected: " + implausible
                                    : "Moffat fit did not converge (" + psf::toString(fit.convergence) + ")";
  return out;
}

#ifdef ST_GUI_HAVE_PIPELINE
/// A cube written by `synthtrack-cli preprocess` (header STPREP): opened as prepared, not pre-processed again
/// (that would find no stars or background, and measure the sky rate from whatever moves): the header's PSF,
/// sigma_n and sky rate are taken, a zero-biased cube is matched-filtered with the header's PSF
/// (pipeline::searchInputFromPrepared, as `search --preprocessed`), a filtered one searched as is.
ui::PreparedView openPrepared(const FrameCube& raw, const pipeline::PreparedHeader& h, ProgressSink& progress,
                              CancelToken& cancel) {
  pipeline::PreparedSearchInput in = pipeline::searchInputFromPrepared(raw, {}, progress, cancel);
  auto prep = std::make_shared<pipeline::Prepared>();
  prep->psfFitted = h.psf.has_value();
  prep->psf = h.psf.value_or(psf::Moffat::fromFwhm(3.0, pipeline::kDefaultPsfBeta));
  prep->sigmaN = h.sigmaN.value_or(0.0);
  prep->skyRate = h.skyRate;
  prep->skyRateMeasured = true;
  if (h.state == pipeline::PreparedState::ZeroBiased) {
    // The co-moving fit's model of the per-pixel background (header BGWINS...) and the movers that were left
    // out of it (the sidecar preprocess wrote beside the file), as when the frames are pre-processed here.
    pipeline::PreparedBackgroundModel model = pipeline::readPreparedBackgroundModel(h, raw, in.notes);
    prep->backgroundWindows = std::move(model.windows);
    if (model.movers) {
      prep->movers = std::move(*model.movers);
      in.notes.push_back(
          "the co-moving fit models the per-pixel background's windows (header BGWINS) and the " +
          std::to_string(prep->movers.size()) + " mover(s) left out of it (" + model.sidecar + ")");
    } else if (!model.sidecarError.empty()) {
      in.warnings.push_back(model.sidecarError +
                            "; the co-moving fit takes no mover as left out of the per-pixel background");
    } else if (!prep->backgroundWindows.empty()) {
      in.notes.push_back("no sidecar " + model.sidecar +
                         ": the co-moving fit models the per-pixel background's windows (header BGWINS) as "
                         "if no mover had been left out of it");
    }
  }
  prep->notes = in.notes;
  ui::PreparedView view;
  if (h.state == pipeline::PreparedState::ZeroBiased) {
    auto unfiltered = std::make_shared<search::FilteredCube>();
    unfiltered->frames = raw;  // the fit's frames (the GUI keeps `raw` for viewing: one more copy)
    unfiltered->sigmaF = prep->sigmaN;
    unfiltered->skyRate = h.skyRate;
    unfiltered->psfFwhmPx = prep->psf.fwhm();
    view.unfiltered = std::move(unfiltered);
  }
  auto filtered = std::make_shared<search::FilteredCube>(std::move(in.cube));
  char line[512];
  std::snprintf(line, sizeof line,
                "opened as a prepared cube (%s), not pre-processed again · PSF FWHM %.2f px (header) · σ_F %.3g "
                "· sky rate (%.4g, %.4g) px/s (header)%s",
                h.evidence.c_str(), prep->psf.fwhm(), filtered->sigmaF, h.skyRate.vx, h.skyRate.vy,
                raw.hasFrameOffsets() ? " · registered frames (per-frame offsets from the FRAMES table)" : "");
  view.summary = line;
  for (const auto& w : in.warnings)
    view.summary += "\n• warning: " + w;
  for (const auto& note : in.notes)
    view.summary += "\n• " + note;
  view.filtered = std::move(filtered);
  view.products = std::move(prep);
  return view;
}

/// The masters from the calibration stage's bias, flat and dark lists (loaded as the CLI's preprocess does,
/// app/common/observation_pipeline.hpp), or none when all three are empty. Throws st::InputError naming the
/// file (unreadable, or of another size or binning than the science frames).
std::optional<calib::MasterCalibration> buildMasters(const FrameCube& raw,
                                                     const std::vector<ui::StageSpec>& stages,
                                                     const calib::CalibParams& params, ProgressSink& progress,
                                                     CancelToken& cancel, std::vector<std::string>& warnings) {
  const auto biasFiles = ui::stageFiles(stages, "bias");
  const auto flatFiles = ui::stageFiles(stages, "flat");
  const auto darkFiles = ui::stageFiles(stages, "dark");
  if (biasFiles.empty() && flatFiles.empty() && darkFiles.empty()) return std::nullopt;
  progress.report(0.0, "loading calibration frames");
  const FrameCube bias = loadCalibrationFrames(biasFiles, std::nullopt, progress, cancel);
  const FrameCube dark = loadCalibrationFrames(darkFiles, std::nullopt, progress, cancel);
  const FrameCube flat = loadCalibrationFrames(flatFiles, std::nullopt, progress, cancel);
  for (const FrameCube* c : {&bias, &dark, &flat})
    warnings.insert(warnings.end(), c->warnings.begin(), c->warnings.end());
  progress.report(0.0, "building master calibration frames");
  calib::MasterCalibration m = calib::buildMasters(bias, dark, flat, raw, params, progress, cancel);
  warnings.insert(warnings.end(), m.warnings.begin(), m.warnings.end());
  return m;
}

/// "bias (2 folders), flat (3 files)" for the summary.
std::string mastersSummary(const std::vector<ui::StageSpec>& stages) {
  std::string out;
  for (const char* key : {"bias", "flat", "dark"}) {
    const auto paths = ui::stageFiles(stages, key);
    if (paths.empty()) continue;
    if (!out.empty()) out += ", ";
    out += std::string(key) + " (";
    for (std::size_t i = 0; i < paths.size(); ++i)
      out += (i ? ", " : "") + std::filesystem::path(paths[i]).filename().string();
    out += ")";
  }
  return out;
}

ui::PreparedView runPreprocess(std::shared_ptr<const FrameCube> raw, const std::vector<ui::StageSpec>& stages,
                               ProgressSink& progress, CancelToken& cancel) {
  if (const auto h = pipeline::recognisePreparedHeader(raw->header, pipeline::cubeSource(*raw)))
    return openPrepared(*raw, *h, progress, cancel);
  // The stages' settings by stable key onto the typed parameters (session/preprocess_settings.hpp); the
  // calibration stage off ignores the headers' image sections (overscan, trim) and takes no bias/flat/dark.
  pipeline::PreprocessParams p = session::preprocessParams(ui::preprocessSettings(stages));
  std::vector<std::string> calibWarnings;
  if (ui::stageEnabled(stages, session::kCalibrationStageKey)) {
    SubProgress calibProgress(progress, 0.0, 0.1);
    p.masters = buildMasters(*raw, stages, p.calib, calibProgress, cancel, calibWarnings);
  }
  SubProgress prepProgress(progress, p.masters ? 0.1 : 0.0, 1.0);
  // preprocess takes the cube by value and works in place; the GUI keeps the raw frames for viewing, so
  // this is the one documented extra copy of the cube.
  pipeline::Prepared prep = pipeline::preprocess(*raw, p, prepProgress, cancel);

  ui::PreparedView view;
  const double fwhm = prep.psf.fwhm();
  auto filtered = std::make_shared<search::FilteredCube>(std::move(prep.filtered));
  auto unfiltered = std::make_shared<search::FilteredCube>();
  unfiltered->frames = std::move(prep.frames);
  unfiltered->sigmaF = prep.sigmaN;
  unfiltered->skyRate = prep.skyRate;
  unfiltered->psfFwhmPx = fwhm;
  Image zeroed(unfiltered->frames.width(), unfiltered->frames.height(), 0.0f);
  if (!unfiltered->frames.empty())
    for (std::size_t i = 0; i < zeroed.size(); ++i)
      zeroed.pixels[i] = unfiltered->frames.frame(0)[i] == 0.0f ? 1.0f : 0.0f;
  view.layers.emplace_back("Background (subtracted)", std::move(prep.background));
  view.layers.emplace_back("Noise σ per pixel", std::move(prep.noise));
  view.layers.emplace_back("Zeroed pixels, frame 0 (stars, cosmic rays, masks)", std::move(zeroed));
  char line[512];
  std::snprintf(
      line, sizeof line,
      "σ_n %.3g counts · σ_F %.3g · PSF FWHM %.2f px (%s) · sky rate (%.4g, %.4g) px/s%s · %zu stars · "
      "%zu cosmic-ray pixels · %.1f s",
      prep.sigmaN, filtered->sigmaF, fwhm, prep.psfFitted ? "fitted" : "fallback", prep.skyRate.vx,
      prep.skyRate.vy, prep.skyRateMeasured ? " measured" : "", prep.stars.size(), prep.cosmicRays,
      prep.elapsedS);
  view.summary = line;
  if (p.masters) view.summary += "\n• calibrated with " + mastersSummary(stages);
  for (const auto& w : calibWarnings)
    view.summary += "\n• warning: " + w;
  for (const auto& w : prep.calibration.warnings)
    view.summary += "\n• warning: " + w;
  for (const auto& note : prep.notes)
    view.summary += "\n• " + note;
  view.filtered = std::move(filtered);
  view.unfiltered = std::move(unfiltered);
  view.products = std::make_shared<const pipeline::Prepared>(std::move(prep));
  return view;
}
#endif

// The demo is simulated once (tens of seconds on 2 cores) and cached as a FITS cube with its frame times
// and WCS (st::io::writeCube), so later starts open it in seconds. The cache is keyed by preset and seed;
// a cache that fails to load is simulated again.
FrameCube simulateDemo(ProgressSink& progress, CancelToken& cancel) {
  const QString dir = QStandardPaths::writableLocation(QStandardPaths::CacheLocation);
  const std::string path = (dir + QString("/paper-neo-seed%1.fits").arg(kDemoSeed)).toStdString();
  if (!dir.isEmpty() && QFileInfo::exists(QString::fromStdString(path))) {
    try {
      SubProgress sub(progress, 0.0, 1.0);
      return io::loadFrames({path}, io::LoadOptions{}, sub, cancel);
    } catch (const Cancelled&) {
      throw;
    } catch (const std::exception&) {
      std::error_code ignored;
      std::filesystem::remove(path, ignored);  // stale or damaged: simulate again
    }
  }
  SubProgress simProgress(progress, 0.0, 0.9);
  FrameCube cube = sim::simulate(sim::preset("paper-neo"), kDemoSeed, simProgress, cancel).cube;
  if (!dir.isEmpty() && QDir().mkpath(dir)) {
    progress.report(0.9, "caching the demo cube");
    const std::string tmp = path + ".part";
    try {
      io::writeCube(tmp, cube);
      std::filesystem::rename(tmp, path);
    } catch (const std::exception&) {
      std::error_code ignored;
      std::filesystem::remove(tmp, ignored);  // a cache is optional
    }
  }
  return cube;
}

}  // namespace

ui::CoreServices makeCoreServices() {
  ui::CoreServices s;
  s.loadFrames = [](const std::vector<std::string>& inputs, ProgressSink& progress, CancelToken& cancel) {
    return io::loadFrames(inputs, io::LoadOptions{}, progress, cancel);
  };
  s.planOpen = [](const std::vector<std::string>& inputs, std::size_t budgetBytes, CancelToken& cancel) {
    return pipeline::planOpen(inputs, io::LoadOptions{}, budgetBytes, workerCount(), cancel);
  };
  s.simulateDemo = simulateDemo;
#ifdef ST_GUI_HAVE_PIPELINE
  s.preprocessStages = ui::describedStages();
  s.preprocess = runPreprocess;
  s.fitCandidate = fitCandidate;
#endif
  s.makeBackend = [](ui::BackendKind kind, std::string& message) {
    const BackendChoice choice = kind == ui::BackendKind::Cpu   ? BackendChoice::Cpu
                                 : kind == ui::BackendKind::Gpu ? BackendChoice::Cuda
                                                                : BackendChoice::Auto;
    BackendSelection sel = makeBackend(choice);
    message = sel.message;
    return std::move(sel.backend);
  };
  s.radialProfile = profileAt;
  s.pixelToSky = [](const FrameCube& cube, double x, double y) -> std::optional<std::pair<double, double>> {
    if (!cube.wcs) return std::nullopt;
    const Wcs::Sky sky = cube.wcs->pixelToSky(x, y);
    return std::make_pair(sky.raDeg, sky.decDeg);
  };
  s.gpuNames = gpuNames();  // the devices' names, e.g. "NVIDIA H100 80GB HBM3, 79.1 GiB"
  return s;
}

}  // namespace st::app

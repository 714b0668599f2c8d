#include "st/pipeline/preprocess.hpp"

#include "preprocess_psf.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <future>
#include <mutex>
#include <optional>
#include <sstream>
#include <system_error>

#include "../common/opencv_threads.hpp"
#include "st/common/env_flag.hpp"
#include "st/common/error.hpp"
#include "st/common/memory_budget.hpp"
#include "st/common/moving_mask.hpp"
#include "st/common/parallel_cap.hpp"
#include "st/common/prefault.hpp"
#include "st/detect/hot_pixels.hpp"
#include "st/detect/sky_stack.hpp"
#include "st/detect/star_subtraction.hpp"
#include "st/pipeline/preprocess_accelerator.hpp"
#include "st/common/cpu_time.hpp"
#include "st/common/timed_parts.hpp"
#include "st/common/trace.hpp"
#include "st/pipeline/registration_stage.hpp"
#include "st/psf/psf_star.hpp"
#include "st/stack/matched_filter.hpp"

namespace st::pipeline {
namespace {

// `m` locked, the wait for it traced as `waiting` (st/common/trace.hpp).
std::unique_lock<std::mutex> lockTraced(std::mutex& m, const char* waiting) {
  const trace::Scope traced(waiting);
  return std::unique_lock(m);
}

// A step a device may make for pre-processing (issue 16: the sky rate's block sums, the stacks at the sky
// rate, their filtered SNR maps): asked and made counted; after the device's first st::GpuError a warning in
// the notes ("warning: WHAT fell back to the CPU (device: message)") and none from then on: the CPU makes
// them.
class DeviceStep {
 public:
  DeviceStep(const PreprocessAccelerator* accel, std::string what, std::vector<std::string>& notes)
      : m_accel(accel), m_what(std::move(what)), m_notes(notes) {}
  /// call() is the device's (an optional: none when it declines); none here when it failed before or fails
  /// now.
  template <class Call>
  auto operator()(const Call& call) -> decltype(call()) {
    ++asked;
    if (m_failed) return std::nullopt;
    const trace::Scope traced("device: " + m_what);
    try {
      auto result = call();
      made += result ? 1 : 0;
      return result;
    } catch (const GpuError& e) {
      m_failed = true;
      m_notes.push_back("warning: " + m_what + " fell back to the CPU (" + m_accel->name() + ": " + e.what() +
                        ")");
      return std::nullopt;
    }
  }
  int asked = 0, made = 0;

 private:
  const PreprocessAccelerator* m_accel;
  std::string m_what;
  std::vector<std::string>& m_notes;
  bool m_failed = false;
};

}  // namespace

Prepared preprocess(FrameCube raw, const PreprocessParams& params, ProgressSink& progress,
                    CancelToken& cancel) {
  // The stages allocate and free frame- and stack-sized buffers on every thread; kept by the heap instead of
  // given back, they are not faulted and zeroed again by the kernel each time (issue 15: 1500 x 512^2 on the
  // 2-core VM faulted 1.58 M pages, ~1.7 CPU-s of system time, about half of them such reuse).
  const HeapReuseScope heapReuse;
  st::detail::useOpenCvSequentially();
  const auto start = std::chrono::steady_clock::now();
  auto last = start;
  double lastCpu = processCpuSeconds();
  Prepared out;
  // A device may be downloading frames into `out`'s cubes behind the stages after the one that made them
  // (the frame backgrounds' behind registration and the sky rate; the zero-biased cube's behind the noise
  // model and the matched filter): waited for where the host frames are read, and before `out` is freed
  // when a stage throws.
  const struct HostCopiesGuard {
    PreprocessAccelerator* accel;
    ~HostCopiesGuard() {
      if (!accel) return;
      try {
        accel->allowFrameDownloadBehind(false);
        accel->finishHostCopies();
      } catch (...) {  // the stage's own exception is on its way out
      }
    }
  } hostCopies{params.accelerator};
  auto lap = [&](const char* stage) {
    const auto now = std::chrono::steady_clock::now();
    const double cpu = processCpuSeconds();
    out.stageSeconds.emplace_back(stage, std::chrono::duration<double>(now - last).count());
    out.stageCpuSeconds.emplace_back(stage, cpu - lastCpu);
    trace::record(stage, last, now);
    last = now;
    lastCpu = cpu;
  };
  if (raw.empty()) throw InputError("pre-processing: no frames");
  // Said here, not after a second of stages: the per-pixel background needs that many samples of a pixel.
  if (raw.frameCount() < params.background.minSamples)
    throw InputError("pre-processing: " + std::to_string(raw.frameCount()) +
                     " frame(s); synthetic tracking needs at least " +
                     std::to_string(params.background.minSamples) +
                     " (the per-pixel background measures each pixel's level over that many frames)");
  out.frames = std::move(raw);
  FrameCube& cube = out.frames;
  const calib::MasterCalibration noMasters;
  const calib::MasterCalibration& masters = params.masters ? *params.masters : noMasters;
  calib::CalibrationPlan calibration = calib::planCalibration(cube, masters, params.calib);
  // With a device and no trim, the pixels are calibrated on the device as part of the frame backgrounds'
  // upload (issue 16: the same floats, without a pass over the host cube); the bad pixels, which do not
  // depend on the pixel values, are masked first.
  const bool calibrateOnDevice =
      params.accelerator && params.frameBackground.enabled && !calib::trims(cube, calibration);
  if (!calibrateOnDevice) {
    SubProgress sub(progress, 0.0, 0.1);
    calib::applyPixelCalibration(cube, calibration, sub, cancel);
  }
  out.calibration = calib::finishCalibration(cube, masters, calibration);
  lap("calibrate");
  // This function gates its reads of the host frames until the cosmic rays (registration frame by frame,
  // the sky rate's CPU fallbacks, and every frame before the cosmic rays): a device may download the frame
  // backgrounds' frames behind registration and the sky rate, which read its own copy.
  if (params.accelerator) params.accelerator->allowFrameDownloadBehind(true);
  {
    SubProgress sub(progress, 0.1, 0.12);
    out.frameBackgrounds =
        calibrateOnDevice
            ? calibrateAndRemoveFrameBackgroundsOn(params.accelerator, cube, calibration,
                                                   params.frameBackground, sub, cancel, out.notes)
            : removeFrameBackgroundsOn(params.accelerator, cube, params.frameBackground, sub, cancel,
                                       out.notes);
    if (out.frameBackgrounds.framesSkipped > 0)
      out.notes.push_back(std::to_string(out.frameBackgrounds.framesSkipped) +
                          " frame(s) without a background model (SEP failed): their sky level was kept");
  }
  if (params.accelerator) params.accelerator->allowFrameDownloadBehind(false);
  lap("frame backgrounds");
  // The frames are as the frame backgrounds left them: a device that kept them reads them from there for
  // the global background and the hot pixels (issue 16).
  if (params.accelerator) params.accelerator->framesUnchangedSinceFrameBackgrounds(cube, true);
  out.global = globalBackgroundOn(params.accelerator, cube, params.background.global, out.notes);
  if (params.findHotPixels) {
    const auto hot = findHotPixelsOn(params.accelerator, cube, out.global, {}, cancel, out.notes);
    out.hotPixels = detect::maskPixelsInAllFrames(cube, hot);
    if (params.accelerator) params.accelerator->maskedInAllFrames(cube, hot);
  }
  lap("global background");
  // With a device for the matched filter, the filtered cube's host buffer (1.5 GB for 1500 x 512^2: 0.5-1.5 s
  // of page faults on one core) is allocated on another thread while the stages up to the filter run (from
  // here, after the hot-pixel mask's own allocation: the device stages from the per-pixel background on take
  // only ~0.3 s); the device then downloads into it (issue 16). Without one, the CPU filter's copy allocates
  // it as before.
  std::future<PixelVector> filteredBuffer;
  if (params.accelerator && params.matchedFilter && params.keepZeroBiased)
    filteredBuffer = std::async(std::launch::async, [n = cube.pixels().size()] {
      return prefaultedPixels(n, 1);  // its pages on this thread alone: the stages meanwhile use every core
    });
  bool rateFromRegistration = false;
  std::size_t framesMoved = 0;
  {
    SubProgress sub(progress, 0.1, 0.12);
    rateFromRegistration = registerFramesStage(out, cube, params, sub, cancel, &framesMoved);
  }
  lap("registration");
  // Unless registration moved frames, the pixels are those the frame backgrounds left: a device that kept
  // them need not upload them again for the prefetch below.
  if (params.accelerator) params.accelerator->framesUnchangedSinceFrameBackgrounds(cube, framesMoved == 0);
  // The cube does not change again until the per-pixel background but at the cosmic-ray fills (patched into
  // the device's copy below; the sky rate, static sources and PSF only read it): a device may upload it
  // meanwhile and make the sky rate's and the static sources' stacks from it (issue 16). The guard,
  // destroyed before `out`, waits for that.
  const std::shared_ptr<void> prefetched = params.accelerator ? params.accelerator->prefetch(cube) : nullptr;
  DeviceStep sumsStep(params.accelerator, "the sky rate's block means and stacks", out.notes);
  detect::ShiftedSumsProvider deviceSums;
  if (params.accelerator)
    deviceSums = [&sumsStep, accel = params.accelerator](const FrameCube& c,
                                                         const std::vector<detect::ShiftedBlock>& blocks,
                                                         double background, detect::ShiftedSumsForm form) {
      auto sums = sumsStep([&] { return accel->shiftedSums(c, blocks, background, form); });
      // Not made, or not of the blocks' shape (the sky rate then drops it): the CPU reads the host frames.
      const std::size_t np = c.framePixels();
      const bool shaped = sums && sums->size() == blocks.size() &&
                          std::all_of(sums->begin(), sums->end(), [&](const detect::ShiftedSums& s) {
                            return form == detect::ShiftedSumsForm::DoubleMeans
                                       ? s.doubleMean.size() == np
                                       : (s.mean.size() == np && s.frames.size() == np) ||
                                             (s.sum.size() == np && s.count.size() == np);
                          });
      if (!shaped) {
        accel->finishHostCopies();
        sums.reset();
      }
      return sums;
    };
  DeviceStep correlationStep(params.accelerator, "the sky rate's phase correlations", out.notes);
  detect::PhaseCorrelationProvider deviceCorrelations;
  if (params.accelerator)
    deviceCorrelations = [&correlationStep,
                          accel = params.accelerator](const detect::PhaseCorrelationBatch& b) {
      return correlationStep([&] { return accel->phaseCorrelations(b); });
    };
  if (params.skyRate) {
    out.skyRate = *params.skyRate;
  } else if (!rateFromRegistration) {
    const detect::SkyRate r =
        detect::measureSkyRate(cube, out.global.mean, out.global.sigma, params.skyRateParams, cancel,
                               &deviceSums, &deviceCorrelations);
    out.skyRate = r.rate;
    out.skyRateMeasured = r.reliable;
    std::ostringstream note;
    note << r.note << ": (" << r.rate.vx << ", " << r.rate.vy << ") px/s";
    out.notes.push_back(note.str());
    if (!r.parts.parts.empty()) out.notes.push_back("sky rate: " + r.parts.text());
    out.skyRateMeasurement = r;
    if (params.accelerator && sumsStep.asked > 0)
      out.notes.push_back("sky rate: the block pairs' means and the chain's block stacks, " +
                          std::to_string(sumsStep.made) + " of " + std::to_string(sumsStep.asked) +
                          " sets on " + params.accelerator->name());
    if (params.accelerator && correlationStep.asked > 0)
      out.notes.push_back(
          "sky rate: the chain's phase correlations, " + std::to_string(correlationStep.made) + " of " +
          std::to_string(correlationStep.asked) + " batches on " + params.accelerator->name());
  }
  // Stacks at the sky rate on a device, from the cube prefetch() is uploading (issue 16): the cosmic rays'
  // protection, then the static sources and the PSF. A device failure: a note, the CPU stacks from then on.
  DeviceStep stacksStep(params.accelerator, "the stacks at the sky rate", out.notes);
  // The static-source search has the stacks of the thirds and halves made on a thread of the cache's beside
  // its own device calls (the stacks and their SNR maps): one at a time, and their DeviceSteps' counts and
  // notes with them.
  std::mutex stackCalls;
  detect::SkyStackCache::Provider deviceStacks;
  if (params.accelerator)
    deviceStacks = [&stacksStep, &stackCalls, accel = params.accelerator](
                       const FrameCube& c, Velocity rate, double subtract, std::size_t firstFrame,
                       std::size_t endFrame) {
      const auto lock = lockTraced(stackCalls, "device stack: waits for the device");
      return stacksStep([&] { return accel->skyStack(c, rate, subtract, firstFrame, endFrame); });
    };
  // The cosmic rays' protection stacks (the frames as the frame backgrounds left them, at the sky rate, none
  // subtracted) made on the device beside the wait for the frames' download below and the cosmic rays' noise
  // (issue 16); the notes of this thread wait in `waitedNote` until no other thread may add one.
  detect::SkyStackCache protectionStacks;
  if (deviceStacks && params.removeCosmicRays && params.stacksAhead) {
    protectionStacks.setProvider(deviceStacks);
    protectionStacks.prefetch(cube, out.skyRate, 0.0,
                              calib::protectionRanges(cube.frameCount(), params.cosmicRays.protectBlocks));
  }
  std::string waitedNote;
  if (params.accelerator) {
    // Every stage from here reads the host frames.
    const auto t0 = std::chrono::steady_clock::now();
    const trace::Scope waiting("sky rate: waits for the frames' download");
    params.accelerator->finishHostCopies();
    const double waited = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (waited >= 0.001)
      waitedNote =
          "sky rate: waited " + std::to_string(waited) + " s after it for the frame backgrounds' download";
  }
  if (!params.removeCosmicRays && !waitedNote.empty()) out.notes.push_back(waitedNote);
  lap("sky rate");
  {
    // The cosmic rays, static sources and PSF make a few dozen canvas-sized images on this thread (the stacks
    // at the sky rate and their analyses): their pages faulted on every core now, not one by one there.
    const MovingMask canvas(cube, out.skyRate);
    const std::size_t canvasBytes =
        static_cast<std::size_t>(canvas.canvasWidth()) * canvas.canvasHeight() * sizeof(float);
    // Benchmark knob: ST_NO_HEAP_WARM=1 leaves it out (for before/after figures from one binary).
    static const bool noWarm = envFlag("ST_NO_HEAP_WARM");
    const trace::Scope traced("warming this thread's heap");
    if (!noWarm)
      HeapReuseScope::warmCallerHeap(std::min<std::size_t>(32 * canvasBytes, std::size_t{512} << 20));
  }
  detect::StaticSourceParams sp = params.stars;
  sp.psfFwhmPx = params.givenPsf ? params.givenPsf->fwhm() : params.psfFwhmPx;
  if (!sp.saturationLevel) sp.saturationLevel = detail::saturationCounts(cube, params, out.calibration);
  calib::CosmicRayResult cr;
  if (params.removeCosmicRays) {
    SubProgress sub(progress, 0.1, 0.3);
    calib::CosmicRayParams cp = params.cosmicRays;
    cp.skyRate = out.skyRate;
    if (!cp.saturationLevel) cp.saturationLevel = sp.saturationLevel;
    cp.fill = calib::CosmicRayParams::Fill::TimeNeighbours;  // zeroed after background subtraction
    DeviceStep preTestStep(params.accelerator, "the cosmic rays' pre-test", out.notes);
    calib::CosmicRayPreTest devicePreTest;
    if (params.accelerator)
      devicePreTest = [&preTestStep, &stackCalls, accel = params.accelerator](const FrameCube& c, float thr) {
        const auto lock = lockTraced(stackCalls, "cosmic-ray pre-test: waits for the device");
        return preTestStep([&] { return accel->cosmicRayPreTest(c, thr); });
      };
    detect::SkyStackCache::Provider crStacks;
    if (deviceStacks)
      crStacks = [&](const FrameCube& c, Velocity rate, double subtract, std::size_t firstFrame,
                     std::size_t endFrame) {
        bool found = false;  // one declined ahead is asked again
        std::optional<detect::SkyStack> s =
            protectionStacks.takePrefetched(c, rate, subtract, firstFrame, endFrame, &found);
        return found ? std::move(s) : deviceStacks(c, rate, subtract, firstFrame, endFrame);
      };
    cr = calib::removeCosmicRays(cube, cp, sub, cancel, &crStacks, &devicePreTest);
    protectionStacks = detect::SkyStackCache();  // settled: its thread joined, stacks not asked for freed
    if (!waitedNote.empty()) out.notes.push_back(waitedNote);
    if (cr.preTestProvided) out.notes.push_back(params.accelerator->lastNote());  // its last device step
    out.cosmicRaysPerFrame = cr.perFrame;
    out.cosmicRays = cr.total;
    if (!cr.parts.parts.empty())
      out.notes.push_back("cosmic rays: " + cr.parts.text() + "; the seeds' pre-test " +
                          (cr.preTestProvided ? "on the device" : "on the CPU"));
    if (params.accelerator) {
      params.accelerator->patchPrefetch(cube, cr.pixels);  // the fills, on the device
      out.notes.push_back("cosmic rays: " + std::to_string(cr.protectionStacksProvided) + " of " +
                          std::to_string(cr.protectionStacks) + " protection stacks at the sky rate on " +
                          params.accelerator->name());
    }
    if (cr.sourceSeeds > 0)
      out.notes.push_back(std::to_string(cr.sourceSeeds) +
                          " pixel(s) that stood above their time neighbours like cosmic-ray hits were kept: "
                          "each is the core of a source the PSF resolves (a bright mover, a variable star), "
                          "not a hit");
  }
  lap("cosmic rays");
  detect::StaticSources stars;
  // The stacks at the sky rate, made once for the PSF's catalogue, the PSF and the static-source search (the
  // cube does not change until the per-pixel background).
  detect::SkyStackCache skyStacks;
  if (deviceStacks) skyStacks.setProvider(deviceStacks);
  skyStacks.allowPrefetch(params.stacksAhead);
  // Their matched-filtered SNR maps (2 per static-source search, 4 when it looks at the halves of the frames)
  // on the device too: the same values.
  DeviceStep snrStep(params.accelerator, "the static sources' filtered SNR", out.notes);
  if (params.accelerator)
    skyStacks.setSnrProvider(
        [&snrStep, &stackCalls, accel = params.accelerator](const detect::FilteredSnrInputs& in) {
          const auto lock = lockTraced(stackCalls, "filtered SNR: waits for the device");
          return snrStep([&] { return accel->filteredSnr(in); });
        });
  if (params.givenPsf) {
    SubProgress sub(progress, 0.3, 0.4);
    stars = detect::findStaticSources(cube, out.skyRate, out.global.mean, sp, sub, cancel, &skyStacks);
    out.notes.push_back("static sources: " + stars.parts.text());
    lap("static sources");
    out.stars = stars.stars;
    out.psf = *params.givenPsf;
    out.psfFitted = true;  // fitted on the reference region
  } else {
    // The PSF from the sky-rate stack before the per-pixel background, on a catalogue of the sources seen
    // per pixel at the assumed FWHM (movers left out; no filtered detection, halves' test or footprints).
    // The fit takes the brightest stars isolated from these sources: a neighbour seen only after the filter
    // no longer makes a star crowded. The whole static-source search then runs once, at the fitted FWHM (or
    // the assumed one where the fit fails): its wing radii and dilation are the stars' own (Lowell's 1.9 px
    // stars masked as 3 px ones lose 10.6% of the pixels). Until issue 16 the whole search ran at the
    // assumed FWHM first and again when the fit was off by more than 15%; on paper-neo's 1500 frames the
    // catalogue takes ~half of a whole search.
    // Benchmark knob: ST_PSF_FULL_CATALOGUE=1 runs the whole search there (the time of before, when the fit
    // was off by more than 15%).
    static const bool fullCatalogue = envFlag("ST_PSF_FULL_CATALOGUE");
    std::optional<double> psfNoise;
    detect::StaticSourceParams forPsf = sp;
    forPsf.catalogueOnly = !fullCatalogue;
    SubProgress stackSub(progress, 0.3, 0.31);
    const detect::SkyStack& psfStack = skyStacks.stack(cube, out.skyRate, out.global.mean, stackSub, cancel);
    // A given PSF star (psfStar) needs neither the catalogue nor the stack's noise (measurePsfAt).
    if (!params.psfStar) {
      // The stack's robust noise (the PSF fit's amplitude cut; ~7 ms of one thread's sorting on paper-neo's
      // 1.8M-pixel stack) on a thread of its own beside the catalogue: the cache's stacks stay where they are
      // (std::map) while the catalogue adds the thirds'. Without a thread, measurePsf measures it.
      std::future<double> noiseAhead;
      try {
        noiseAhead = std::async(std::launch::async, [&psfStack] {
          const trace::Scope traced("PSF: the stack's noise");
          const ParallelThreadCap cap(2);
          return psf::robustImageNoise(psfStack.mean);
        });
      } catch (const std::system_error&) {
      }
      {
        SubProgress sub(progress, 0.31, 0.34);
        stars =
            detect::findStaticSources(cube, out.skyRate, out.global.mean, forPsf, sub, cancel, &skyStacks);
      }
      out.notes.push_back("static sources, the PSF's catalogue: " + stars.parts.text());
      out.stars = stars.stars;
      if (noiseAhead.valid()) psfNoise = noiseAhead.get();
    }
    lap("static sources for the PSF");
    // The search's stacks of the halves of the frames made on the device beside the PSF's fits (the search
    // asked for them only once it had found a faint source: ~20 ms of its time on paper-neo's 1500 frames).
    // Its thread may add a device's warning to out.notes meanwhile: the PSF's notes wait in psfNotes.
    detect::prefetchStaticSourceStacks(cube, out.skyRate, out.global.mean, sp, skyStacks);
    std::vector<std::string> psfNotes;
    detail::measurePsfInto(out, psfStack, params, psfNoise, &psfNotes);
    lap("PSF");
    if (out.psfFitted) sp.psfFwhmPx = out.psf.fwhm();
    SubProgress sub(progress, 0.36, 0.4);
    stars = detect::findStaticSources(cube, out.skyRate, out.global.mean, sp, sub, cancel, &skyStacks);
    out.notes.insert(out.notes.end(), psfNotes.begin(), psfNotes.end());  // the search settled the prefetch
    out.notes.push_back("static sources at " + std::string(out.psfFitted ? "the fitted" : "the assumed") +
                        " FWHM: " + stars.parts.text());
    lap("static sources");
  }
  if (params.accelerator) {
    std::ostringstream note;
    note << "stacks at the sky rate: " << skyStacks.made() << " made (" << skyStacks.provided() << " on "
         << params.accelerator->name() << ", " << skyStacks.prefetched()
         << " of them beside the host work in " << skyStacks.prefetchSeconds() << " s) in "
         << skyStacks.seconds() << " s; their filtered SNR maps: " << snrStep.asked << " (" << snrStep.made
         << " on the device)";
    out.notes.push_back(note.str());
  }
  skyStacks = detect::SkyStackCache();  // its memory (several canvases) is not needed any more
  out.stars = stars.stars;
  out.movers = stars.movers;
  if (!stars.movers.empty()) {
    std::ostringstream note;
    note << stars.movers.size()
         << " source(s) of the sky-rate stack moved between its first and last thirds and were left "
            "unmasked for the search:";
    for (const auto& m : stars.movers)
      note << " (" << m.x << ", " << m.y << ") px moving (" << m.v.vx << ", " << m.v.vy << ") px/s, shift "
           << m.shiftPx << " +- " << m.shiftSigmaPx << " px;";
    out.notes.push_back(note.str());
  }
  std::vector<std::uint8_t> unmeasured;  // pixels whose background had too few samples
  // The movers are left out of the per-pixel background too: a slow one covers a pixel for a good part of
  // the frames and would raise its background (and lose that much of its signal). Where the stars are
  // subtracted (a drifting field), their wide footprints are left out as well.
  detect::MovingMask exclude = stars.mask;
  exclude.add(stars.subtractRegion);
  exclude.add(stars.moverMask);
  // Per-pixel background, star subtraction, zeroing (cosmic-ray pixels, masks, unmeasured pixels,
  // single-frame sources) and residual means: on a device that keeps the cube between them when there is
  // one (issue 16), else stage by stage (pipeline/preprocess_accelerator.cpp).
  ZeroBiasInputs zin;
  zin.background = params.background;
  zin.exclude = &exclude;
  zin.subtractRegion = &stars.subtractRegion;
  zin.starSubtraction = params.starSubtraction;
  zin.cosmicRayPixels = &cr.pixels;
  zin.starMask = &stars.mask;
  zin.moverMask = &stars.moverMask;
  zin.singleFrameSnr = params.singleFrameSnr;
  zin.singleFrameRadiusPx = static_cast<int>(std::ceil(out.psf.fwhm())) + 1;
  zin.removeResidualMean = params.removeResidualMean;
  zin.residualMeshPx = params.residualMeshPx;
  if (params.weightedFilter) zin.noiseModel = &params.noise;
  ZeroBiasResult zb = zeroBiasOn(params.accelerator, cube, zin, progress, cancel, out.notes);
  for (auto& stage : zb.stageSeconds)
    out.stageSeconds.push_back(std::move(stage));
  last = std::chrono::steady_clock::now();
  lastCpu = processCpuSeconds();
  {
    stats::Background& bg = zb.background;
    out.sigmaN = bg.sigmaN;
    out.background = std::move(bg.level);
    out.backgroundWindows = stats::pixelBackgroundWindows(cube, params.background);
    out.noise = std::move(bg.sigma);
    out.noiseMap = std::move(bg.noiseMap);
    unmeasured = std::move(bg.filled);
    if (bg.pixelsFilled > 0) {
      out.notes.push_back(
          std::to_string(bg.pixelsFilled) +
          " pixels had too few background samples (under static sources); their background is "
          "the global mean");
    }
  }
  if (zb.starsAttempted) {
    out.starSubtraction = std::move(zb.starSubtraction);
    const detect::StarSubtraction& ss = out.starSubtraction;
    std::ostringstream note;
    if (ss.applied) {
      note << "stars subtracted (drifting field): a sky-registered template of "
           << static_cast<long long>(std::lround(ss.meanTemplateFrames))
           << " frames on average per pixel, leaving out +-" << params.starSubtraction.windowFraction
           << " of the span around each frame; their cores masked, and " << ss.excessPositions
           << " sky positions whose residuals vary more than " << params.starSubtraction.maxVarianceRatio
           << "x the background; the residuals of " << ss.whitenedPositions
           << " sky positions with a smaller excess divided by its square root; " << ss.pixelsZeroed
           << " pixel-frames without a template zeroed";
    } else
      note << "stars not subtracted (the span is too short for a template outside each frame's window): "
              "masked down to one stack sigma instead";
    out.notes.push_back(note.str());
  }
  out.cosmicRayPixels = std::move(cr.pixels);
  out.staticPixelsZeroed = zb.staticPixelsZeroed;
  out.unmeasuredPixelsZeroed = zb.unmeasuredPixelsZeroed;
  if (out.unmeasuredPixelsZeroed > 0) {
    out.notes.push_back(std::to_string(out.unmeasuredPixelsZeroed) +
                        " pixels seen in some frames but without a measured background (static-mask "
                        "edges, bright static light) zeroed in every frame");
  }
  out.singleFrame = std::move(zb.singleFrame);
  if (params.removeResidualMean) out.residualMeanRms = zb.residualMeanRms;
  if (params.weightedFilter) {
    out.noiseModel = estimateNoiseModelOn(params.accelerator, cube, out.noise, unmeasured, params.noise,
                                          cancel, out.notes);
    out.noiseModel.framesCovering = detect::alignedCoverage(out.registration, cube.width(), cube.height());
  }
  lap("noise model");
  if (params.matchedFilter) {
    SubProgress sub(progress, 0.83, 1.0);
    // The one extra full cube (pixels only: masked samples are already 0, so no mask copy).
    FrameCube& f = out.filtered.frames;
    if (params.keepZeroBiased) {
      // The pixels are written by filterCubeFromOn (a device reads the zero-biased cube and writes the
      // filtered one: no host copy of the cube).
      f = FrameCube(cube.width(), cube.height(), 0);
      if (filteredBuffer.valid()) {
        const auto t0 = std::chrono::steady_clock::now();
        f.pixels() = filteredBuffer.get();
        const double waited = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        if (waited > 0.01)
          out.notes.push_back(
              "matched filter: waited " + std::to_string(waited) +
              " s for the filtered cube's host buffer (allocated since the per-pixel background)");
      }
      f.info() = cube.info();
      f.header = cube.header;
      f.wcs = cube.wcs;
      f.plateScaleArcsecPerPx = cube.plateScaleArcsecPerPx;
    } else {
      // In place: the same pixels as the copy, and no mask (the copy has none; masked samples are 0).
      f = std::move(cube);
      cube = FrameCube();
      f.mask().clear();
      f.mask().shrink_to_fit();
    }
    const stack::FilterKernel kernel = stack::makeFilterKernel(out.psf);
    out.filtered.revision = search::nextCubeRevision();
    const stats::NoiseModel* noise = params.weightedFilter ? &out.noiseModel : nullptr;
    const stack::MatchedFilterResult mf =
        params.keepZeroBiased ? filterCubeFromOn(params.accelerator, cube, f, kernel, sub, cancel, noise,
                                                 out.notes, out.filtered.revision)
                              : filterCubeOn(params.accelerator, f, kernel, sub, cancel, noise, out.notes,
                                             out.filtered.revision);
    out.filtered.sigmaF = mf.sigmaF;
    out.filtered.skyRate = out.skyRate;
    out.filtered.psfFwhmPx = out.psf.fwhm();
    lap("matched filter");
  }
  if (params.accelerator) params.accelerator->finishHostCopies();  // the frames are the host's from here
  // Frames moved onto frame 0's grid by whole pixels (registration) go back onto their own grids, their
  // offsets whole again: the search's N_in then counts only the frames that saw each track position (on
  // frame 0's grid, the pixels a frame does not cover are 0 but inside it). The per-pixel maps (background,
  // noise, noise model) stay on frame 0's grid.
  if (!out.registration.alignedPx.empty()) {
    // The per-pixel background was taken on frame 0's grid: a mover's images in the frames of its
    // background sit at other pixels of the frames' own grids than backgroundWindows describes, so the
    // co-moving fit keeps the paper's model for these frames.
    const bool shifted = std::any_of(out.registration.alignedPx.begin(), out.registration.alignedPx.end(),
                                     [](const auto& s) { return s.first != 0 || s.second != 0; });
    if (shifted) out.backgroundWindows = {};
    if (!out.frames.empty()) detect::restoreWholePixels(out.frames, out.registration, cancel);
    if (!out.filtered.frames.empty())
      detect::restoreWholePixels(out.filtered.frames, out.registration, cancel);
    for (std::size_t n = 0; n < out.registration.offsets.size(); ++n) {
      out.registration.offsets[n].x += out.registration.alignedPx[n].first;
      out.registration.offsets[n].y += out.registration.alignedPx[n].second;
    }
    out.registration.alignedPx.clear();
    lap("whole-pixel alignment undone");
  }
  progress.report(1.0, "pre-processing done");
  out.elapsedS = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace st::pipeline

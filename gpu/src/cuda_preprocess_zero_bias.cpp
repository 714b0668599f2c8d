// CudaPreprocess::zeroBias: the per-pixel background, star subtraction, the zeroing stages and the residual
// means with the cube kept on the device from one upload to one download (issue 16).
#include <functional>
#include <future>

#include "cuda_preprocess.hpp"
#include "residual_means_host.hpp"
#include "resident_cube.hpp"
#include "zero_bias.hpp"

namespace st::gpu {

using namespace preprocess_detail;

namespace {

/// Benchmark knob: ST_GPU_ZERO_BIAS_AS_BEFORE=1 makes the residual means in one piece with the zero-biased
/// cube's download after them, and leaves the noise model's variance map to the noise model stage, as before
/// 2026-12-03, for before/after figures from one binary.
bool zeroBiasAsBefore() {
  return envKnob("ST_GPU_ZERO_BIAS_AS_BEFORE");
}

}  // namespace

bool CudaPreprocess::zeroBias(FrameCube& cube, const pipeline::ZeroBiasInputs& in,
                              pipeline::ZeroBiasResult& out, ProgressSink& progress, CancelToken& cancel) {
  if (stagewise()) return false;
  finishHostCopies();
  m_phase.reset();         // the sky rate's phase-correlation buffers: not needed from here
  m_registration.reset();  // nor registration's
  forgetKept();  // a run before this one's (a failure below leaves none to be taken for this cube's)
  const int w = cube.width(), h = cube.height();
  const std::size_t nf = cube.frameCount(), np = cube.framePixels();
  auto stageStart = std::chrono::steady_clock::now();
  auto lap = [&](const char* stage) {  // the stage's seconds, and its trace event when tracing
    const auto now = std::chrono::steady_clock::now();
    if (trace::enabled()) trace::record(stage, stageStart, now);
    out.stageSeconds.emplace_back(stage, std::chrono::duration<double>(now - stageStart).count());
    stageStart = now;
  };
  KeptCube kc;
  // The zero-biased cube's download, queued chunk by chunk with the residual means, reads kc.pix: a
  // cancellation or failure after the first chunk waits for it before kc is freed.
  const HostCopies::DrainOnError drainOnError(m_copies);
  {
    SubProgress sub(progress, 0.4, 0.65);
    out.background = pixelBackground(cube, in.background, in.exclude, sub, cancel, &kc);
  }
  const std::string bgNote = m_note;
  lap("per-pixel background");
  // The noise model's variance map on the host (~13-17 ms for 512^2) beside the device stages below, from
  // the per-pixel sigma and unmeasured pixels they only read; joined before this returns (the pipeline
  // moves them on).
  m_noiseShape.reset();
  std::future<std::optional<NoiseShape>> noiseShape;
  if (in.noiseModel && !zeroBiasAsBefore())
    noiseShape = std::async(
        std::launch::async,
        [&bg = out.background, params = *in.noiseModel, w, h, &cancel]() -> std::optional<NoiseShape> {
          try {
            NoiseShape n;
            n.model = stats::estimateNoiseModel(FrameCube(w, h, 0), bg.sigma, bg.filled, params, cancel);
            n.sigma = bg.sigma.pixels.data();
            n.sigmaSize = bg.sigma.pixels.size();
            n.unmeasured = bg.filled.data();
            n.unmeasuredSize = bg.filled.size();
            n.hash = noiseShapeHash(bg.sigma, bg.filled);
            n.params = params;
            return n;
          } catch (const std::exception&) {
            return std::nullopt;  // the noise model stage makes it (and reports what is wrong)
          }
        });
  ST_CUDA_CHECK(cudaSetDevice(m_device.ordinal));
  DeviceResources& r = resources();
  cudaStream_t s = r.compute.get();
  const DeviceCubeRef d{kc.pix.get(), kc.hasMask ? kc.mask.get() : nullptr, w, h, static_cast<int>(nf)};
  const float* sigma = out.background.sigma.size() == np ? kc.sigma.get() : nullptr;
  out.starsAttempted = in.subtractRegion && !in.subtractRegion->empty();
  std::string starTiming;
  if (out.starsAttempted) {
    cancel.throwIfCancelled();
    out.starSubtraction =
        subtractStarTemplateOnDevice(cube, d, *in.subtractRegion, sigma, in.starSubtraction, s, &starTiming);
    if (out.starSubtraction.applied && in.starMask) {
      // The sky positions whose residuals vary too much are masked with the cores.
      in.starMask->add(out.starSubtraction.excess);
    }
    progress.report(0.75, "star subtraction (GPU)");
    lap("star subtraction");
  }
  cancel.throwIfCancelled();
  if (in.cosmicRayPixels) zeroPixelsOnDevice(d, *in.cosmicRayPixels, s);
  const MovingMask none;
  const MovingMask& movers = in.moverMask ? *in.moverMask : none;
  if (in.starMask) out.staticPixelsZeroed = zeroMaskedOnDevice(d, *in.starMask, s);
  if (out.starsAttempted && !out.starSubtraction.applied)
    out.staticPixelsZeroed += zeroMaskedOnDevice(d, *in.subtractRegion, s);
  out.unmeasuredPixelsZeroed = zeroUnmeasuredOnDevice(d, out.background.filled, movers, s);
  const float* noise = out.background.sigma.size() == np ? kc.sigma.get() : nullptr;
  out.singleFrame = zeroSingleFrameSourcesOnDevice(d, noise, out.background.sigmaN, in.singleFrameSnr,
                                                   in.singleFrameRadiusPx, &movers, s);
  progress.report(0.8, "zeroing (GPU)");
  lap("zeroing");
  cancel.throwIfCancelled();
  kc.mask = DeviceBuffer<std::uint8_t>();
  kc.sigma = DeviceBuffer<float>();
  Stopwatch rm;
  // The download runs behind the noise model and the filter (HostCopies; finishHostCopies() waits for it),
  // and with the residual means, chunk by chunk of 128 frames behind their own chunks: the host cube is then
  // written before the last kernels have run, so a device failure from there stops the run (st::Error)
  // instead of handing the half-written cube to the CPU.
  const bool behind = !syncDownloads();
  const bool chunks = behind && !zeroBiasAsBefore();
  const auto queueDownload = [&](int f0, int f1) {
    m_copies.enqueue(cube.pixels().data() + static_cast<std::size_t>(f0) * np,
                     kc.pix.get() + static_cast<std::size_t>(f0) * np,
                     static_cast<std::size_t>(f1 - f0) * np * sizeof(float), s, true, "the zero-biased cube");
  };
  bool queued = false;
  if (in.removeResidualMean) {
    // The chunks' cell means go through staging buffer 0 (pinned: the pipelined path), once no upload or
    // download of this stage's uses it.
    r.copy.sync();
    r.stagingFree[0].sync();
    void* pinned = chunks ? r.staging(0) : nullptr;
    const trace::Scope traced("residual means on the device");
    try {
      out.residualMeanRms =
          removeResidualMeansOnDevice(kc.pix.get(), w, h, static_cast<int>(nf), in.residualMeshPx,
                                      in.residualClipSigma, s, chunks ? 128 : 0,
                                      chunks ? std::function<void(int, int)>([&](int f0, int f1) {
                                        queueDownload(f0, f1);
                                        queued = true;
                                      })
                                             : std::function<void(int, int)>(),
                                      pinned, pinned ? kStagingBytes : 0);
      ST_CUDA_CHECK(cudaStreamSynchronize(s));
    } catch (const GpuError& e) {
      if (!queued) throw;
      m_copies.drain();
      throw Error("the residual means failed on " + name() +
                  " after the zero-biased cube's download had begun (" + e.what() + ")");
    }
  } else {
    ST_CUDA_CHECK(cudaStreamSynchronize(s));
  }
  const double rmKernels = rm.lap();
  cancel.throwIfCancelled();
  // Every kernel succeeded: the host cube is written now (or already, chunk by chunk), and the frames kept
  // for the matched filter.
  if (behind) {
    if (!queued) queueDownload(0, static_cast<int>(nf));
  } else
    downloadInPlace(r, cube.pixels().data(), kc.pix.get(), nf * np * sizeof(float), s, "the zero-biased cube",
                    name());
  const double down = rm.lap();
  m_kept = std::move(kc.pix);
  m_keptData = cube.pixels().data();
  m_keptCopiedThere = behind;
  m_keptShapeKey = behind ? cubeShapeKey(cube) : 0;
  m_keptKey = behind ? 0 : cubeKey(cube);
  progress.report(0.83, "residual means (GPU)");
  if (noiseShape.valid()) m_noiseShape = noiseShape.get();
  lap("residual means");
  std::string stages;
  for (const auto& [stage, sec] : out.stageSeconds)
    stages += (stages.empty() ? "" : ", ") + stage + " " + ms(sec);
  m_note = "per-pixel background to residual means on " + name() +
           ", the cube kept on the device: " + stages + " (residual means kernels " + ms(rmKernels) +
           (behind ? ", download queued behind the next stages" : ", download " + ms(down)) +
           "; frames kept for the matched filter); star subtraction: " +
           (starTiming.empty() ? "none" : starTiming) + "; " + bgNote;
  return true;
}

}  // namespace st::gpu

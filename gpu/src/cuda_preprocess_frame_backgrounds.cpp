// CudaPreprocess: the frame backgrounds (stats::removeFrameBackgrounds, SEP per frame) on the device: the
// calibrated cube (and its mask) uploaded, or the raw one calibrated on the device after its upload
// (calibrateAndRemoveFrameBackgrounds: calib::applyPixelCalibration's float steps), SEP's mesh statistics
// and spline on the device with the per-frame filter and spline derivatives on the host
// (frame_backgrounds.*), the frames downloaded.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <functional>

#include "cuda_preprocess.hpp"
#include "st/common/error.hpp"
#include "frame_backgrounds.hpp"

namespace st::gpu {

using namespace preprocess_detail;

namespace {

/// Benchmark knob: ST_GPU_SEP_ON_CPU=1 leaves the frame backgrounds to the CPU (libsep) as before, for
/// before/after figures from one binary.
bool sepOnCpu() {
  return envKnob("ST_GPU_SEP_ON_CPU");
}

/// Benchmark knob: ST_GPU_CALIBRATE_ON_CPU=1 calibrates the pixels on the CPU before the frame backgrounds'
/// upload, as before 2026-12-01.
bool calibrateOnCpu() {
  return envKnob("ST_GPU_CALIBRATE_ON_CPU");
}

/// Benchmark knob: ST_GPU_FRAME_DOWNLOAD_FIRST=1 finishes the frame backgrounds' download before the stage
/// returns, as before 2026-12-03, instead of behind registration and the sky rate. Behind, the stage saves
/// its ~35 ms download and the sky rate loses ~25 ms to it (its own device-to-host copies and host copies
/// share the link and the memory): pre-processing 0.57-0.59 s against 0.59-0.66 s on one H200 host
/// (2026-12-03 03:33 UTC), with 2 copy threads; 6 and every core slowed the sky rate by all they saved.
bool frameDownloadFirst() {
  return envKnob("ST_GPU_FRAME_DOWNLOAD_FIRST");
}

/// The threads of that download's host copy: 2, or ST_GPU_FRAME_DOWNLOAD_THREADS (0: every core).
unsigned frameDownloadThreads() {
  const char* e = std::getenv("ST_GPU_FRAME_DOWNLOAD_THREADS");
  return e && *e ? static_cast<unsigned>(std::strtoul(e, nullptr, 10)) : 2u;
}

/// Each DMA of that download: 32 MiB (a staging buffer), or ST_GPU_FRAME_DOWNLOAD_CHUNK_MB MiB: the sky
/// rate's own small downloads wait behind one such DMA on the copy engine.
std::size_t frameDownloadChunkBytes() {
  const char* e = std::getenv("ST_GPU_FRAME_DOWNLOAD_CHUNK_MB");
  return e && *e ? static_cast<std::size_t>(std::strtoul(e, nullptr, 10)) << 20 : kStagingBytes;
}

}  // namespace

void CudaPreprocess::waitForHostFrames(const FrameCube& cube, std::size_t first, std::size_t end) {
  if (!framesPending(cube) || first >= end) return;
  const float* base = cube.pixels().data();
  const std::size_t np = m_framesPendingFramePixels;
  if (std::exception_ptr e = m_copies.waitFor(base + first * np, base + end * np)) std::rethrow_exception(e);
}

stats::FrameBackgrounds CudaPreprocess::removeFrameBackgrounds(FrameCube& cube,
                                                               const stats::FrameBackgroundParams& params,
                                                               ProgressSink& progress, CancelToken& cancel) {
  return frameBackgrounds(cube, params, progress, cancel, nullptr);
}

std::optional<stats::FrameBackgrounds> CudaPreprocess::calibrateAndRemoveFrameBackgrounds(
    FrameCube& cube, const calib::CalibrationPlan& plan, const stats::FrameBackgroundParams& params,
    ProgressSink& progress, CancelToken& cancel) {
  const std::size_t nf = cube.frameCount(), np = cube.framePixels();
  auto fits = [np](const Image* m) { return !m || m->pixels.size() == np; };
  if (!params.enabled || nf == 0 || sepOnCpu() || calibrateOnCpu() || plan.overscan.size() != nf ||
      plan.darkSeconds.size() != nf || !fits(plan.bias) || !fits(plan.darkPerS) || !fits(plan.flat))
    return std::nullopt;
  return frameBackgrounds(cube, params, progress, cancel, &plan);
}

stats::FrameBackgrounds CudaPreprocess::frameBackgrounds(FrameCube& cube,
                                                         const stats::FrameBackgroundParams& params,
                                                         ProgressSink& progress, CancelToken& cancel,
                                                         const calib::CalibrationPlan* plan) {
  finishHostCopies();
  forgetKept();  // a new cube: the last one's zero-biased frames are not wanted
  m_note.clear();
  dropKeptFrames();
  const std::size_t nf = cube.frameCount(), np = cube.framePixels();
  if (!params.enabled || nf == 0 || sepOnCpu()) {
    if (plan) calib::applyPixelCalibration(cube, *plan, progress, cancel);
    return stats::removeFrameBackgrounds(cube, params, progress, cancel);
  }
  Stopwatch sw;
  progress.report(0.0, "frame backgrounds (GPU)");
  ST_CUDA_CHECK(cudaSetDevice(m_device.ordinal));
  DeviceResources& r = resources();
  const bool hasMask = cube.mask().size() == cube.pixels().size();
  DeviceBuffer<float> pix(nf * np);
  DeviceBuffer<std::uint8_t> mask(hasMask ? nf * np : 0);
  if (hasMask) uploadMask(r, mask.get(), cube.mask().data(), nf * np, r.copy.get(), true);
  auto masterOnDevice = [](const Image* m) { return m ? toDevice(m->pixels) : DeviceBuffer<float>(); };
  DeviceBuffer<float> bias, dark, flat, overscan, darkSeconds;
  if (plan) {
    bias = masterOnDevice(plan->bias);
    dark = masterOnDevice(plan->darkPerS);
    flat = masterOnDevice(plan->flat);
    overscan = toDevice(plan->overscan);
    darkSeconds = toDevice(plan->darkSeconds);
  }
  // Chunk by chunk of 128 frames: each chunk's upload, then on the compute stream its calibration and SEP's
  // meshes while the next chunks upload (as before 2026-12-03 with ST_GPU_FRAME_UPLOAD_WHOLE=1: the whole
  // upload first).
  Uploader up(r, cube.pixels().data(), np);
  Event uploaded;
  const auto chunkReady = [&](int f0, int f1) {
    up.upload(pix.get() + static_cast<std::size_t>(f0) * np, f0, f1, r.copy.get());  // dst: frame f0's place
    uploaded.record(r.copy.get());
    ST_CUDA_CHECK(cudaStreamWaitEvent(r.compute.get(), uploaded.get(), 0));
    if (plan) {
      const std::size_t at = static_cast<std::size_t>(f0);
      PixelCalibrationLaunch pc{pix.get() + at * np,
                                static_cast<std::size_t>(f1 - f0),
                                np,
                                overscan.get() + at,
                                darkSeconds.get() + at,
                                plan->bias ? bias.get() : nullptr,
                                plan->darkPerS ? dark.get() : nullptr,
                                plan->flat ? flat.get() : nullptr};
      launchPixelCalibration(pc, r.compute.get());
    }
  };
  const bool whole = envKnob("ST_GPU_FRAME_UPLOAD_WHOLE");
  double upload = 0.0;
  if (whole) {
    chunkReady(0, static_cast<int>(nf));
    r.compute.sync();
    upload = sw.lap();
  }
  cancel.throwIfCancelled();
  progress.report(0.3, "frame backgrounds (GPU)");
  const SepFrameBackgrounds sep = removeFrameBackgroundsOnDevice(
      pix.get(), hasMask ? mask.get() : nullptr, cube.width(), cube.height(), static_cast<int>(nf),
      params.meshPx, params.filterCells, r.compute.get(), whole ? 0 : 128,
      whole ? std::function<void(int, int)>() : std::function<void(int, int)>(chunkReady));
  sw.lap();
  cancel.throwIfCancelled();
  progress.report(0.7, "frame backgrounds (GPU)");
  // Every kernel succeeded: the host cube is written now (a failure part way stops the run: the CPU would
  // calibrate or subtract the frames written again). Where the pipeline allows it, behind the stages after
  // this one (HostCopies), in pieces of a
  // staging buffer (32 MiB) that a stage needing a few frames first (registration's sampled links on the CPU:
  // waitForHostFrames) moves to the front; the global background, the hot pixels, registration's sampled
  // links and the sky rate read the frames kept here on the device.
  const bool behind = m_frameDownloadBehind && !frameDownloadFirst() && !syncDownloads();
  double down = 0.0;
  // Kept for the prefetch of this cube (its pixels equal these until the pipeline says otherwise), from
  // here: the download reads them there.
  m_sepFrames = std::move(pix);
  m_sepMask = std::move(mask);
  m_sepMaskCurrent = true;
  m_sepMaskVouched = false;
  m_sepFramesData = cube.pixels().data();
  const float* frames = m_sepFrames.get();
  if (behind) {
    const std::size_t perPiece = std::max<std::size_t>(1, kStagingBytes / (np * sizeof(float)));
    std::size_t queued = 0;
    try {
      for (std::size_t f0 = 0; f0 < nf; f0 += perPiece) {
        const std::size_t f1 = std::min(nf, f0 + perPiece);
        m_copies.enqueue(cube.pixels().data() + f0 * np, frames + f0 * np, (f1 - f0) * np * sizeof(float),
                         r.compute.get(), true, "the frame backgrounds", frameDownloadThreads(),
                         frameDownloadChunkBytes());
        queued = f1;
      }
    } catch (const std::exception& e) {
      if (queued == 0) {  // the host cube untouched: the CPU redoes the stage, and these frames are not kept
        dropKeptFrames();
        throw;
      }
      m_copies.drain();  // the pieces queued write the host cube: the CPU may not redo the stage on it
      throw Error("the frame backgrounds' download from " + name() + " could not be queued after frame " +
                  std::to_string(queued) + " (" + e.what() + "), leaving the frames half written");
    }
    m_framesPendingData = cube.pixels().data();
    m_framesPendingFramePixels = np;
  } else {
    downloadInPlace(r, cube.pixels().data(), frames, nf * np * sizeof(float), r.compute.get(),
                    "the frame backgrounds", name());
    down = sw.lap();
  }
  stats::FrameBackgrounds out;
  out.level = sep.level;
  out.rms = sep.rms;
  out.restoredLevel = sep.restored;
  std::size_t finite = 0;
  for (const double l : out.level)
    finite += std::isfinite(l) ? 1 : 0;
  out.framesSkipped = nf - finite;
  m_note =
      std::string(plan ? "calibration and frame backgrounds on " : "frame backgrounds on ") + name() + ": " +
      (whole
           ? "upload" + std::string(plan ? " and calibration " : " ") + ms(upload) + ", meshes "
           : std::string("upload") + (plan ? ", calibration" : "") + " and meshes by chunks of 128 frames ") +
      ms(sep.meshSeconds) + ", filter and splines on the host " + ms(sep.hostSeconds) + ", subtraction " +
      ms(sep.subtractSeconds) +
      (behind ? std::string(", download behind the stages after it") : ", download " + ms(down)) +
      "; frames kept on the device for the global background, hot pixels and prefetch";
  progress.report(1.0, "frame backgrounds (GPU)");
  return out;
}

}  // namespace st::gpu

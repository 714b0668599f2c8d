// CudaPreprocess: the frame backgrounds (stats::removeFrameBackgrounds, SEP per frame) on the device: the
// calibrated cube (and its mask) uploaded, SEP's mesh statistics and spline on the device with the
// per-frame filter and spline derivatives on the host (frame_backgrounds.*), the frames downloaded.
#include <cmath>
#include <cstdlib>
#include <cstring>

#include "cuda_preprocess.hpp"
#include "frame_backgrounds.hpp"

namespace st::gpu {

using namespace preprocess_detail;

namespace {

/// Benchmark knob: ST_GPU_SEP_ON_CPU=1 leaves the frame backgrounds to the CPU (libsep) as before, for
/// before/after figures from one binary.
bool sepOnCpu() {
  const char* e = std::getenv("ST_GPU_SEP_ON_CPU");
  return e && *e && *e != '0';
}

}  // namespace

stats::FrameBackgrounds CudaPreprocess::removeFrameBackgrounds(FrameCube& cube,
                                                               const stats::FrameBackgroundParams& params,
                                                               ProgressSink& progress, CancelToken& cancel) {
  m_note.clear();
  m_sepFrames = DeviceBuffer<float>();
  m_sepMask = DeviceBuffer<std::uint8_t>();
  m_sepFramesData = nullptr;
  m_sepFramesValid = false;
  const std::size_t nf = cube.frameCount(), np = cube.framePixels();
  if (!params.enabled || nf == 0 || sepOnCpu())
    return stats::removeFrameBackgrounds(cube, params, progress, cancel);
  Stopwatch sw;
  progress.report(0.0, "frame backgrounds (GPU)");
  ST_CUDA_CHECK(cudaSetDevice(m_device.ordinal));
  DeviceResources& r = resources();
  const bool hasMask = cube.mask().size() == cube.pixels().size();
  DeviceBuffer<float> pix(nf * np);
  DeviceBuffer<std::uint8_t> mask(hasMask ? nf * np : 0);
  Uploader up(r, cube.pixels().data(), np);
  up.upload(pix.get(), 0, static_cast<int>(nf), r.copy.get());
  if (hasMask) uploadMask(r, mask.get(), cube.mask().data(), nf * np, r.copy.get(), true);
  r.copy.sync();
  const double upload = sw.lap();
  cancel.throwIfCancelled();
  progress.report(0.3, "frame backgrounds (GPU)");
  const SepFrameBackgrounds sep = removeFrameBackgroundsOnDevice(
      pix.get(), hasMask ? mask.get() : nullptr, cube.width(), cube.height(), static_cast<int>(nf),
      params.meshPx, params.filterCells, r.compute.get());
  sw.lap();
  cancel.throwIfCancelled();
  progress.report(0.7, "frame backgrounds (GPU)");
  // Every kernel succeeded: the host cube is written now.
  download(r, cube.pixels().data(), pix.get(), nf * np * sizeof(float), r.compute.get());
  const double down = sw.lap();
  // Kept for the prefetch of this cube (its pixels equal these until the pipeline says otherwise).
  m_sepFrames = std::move(pix);
  m_sepMask = std::move(mask);
  m_sepFramesData = cube.pixels().data();
  stats::FrameBackgrounds out;
  out.level = sep.level;
  out.rms = sep.rms;
  out.restoredLevel = sep.restored;
  std::size_t finite = 0;
  for (const double l : out.level)
    finite += std::isfinite(l) ? 1 : 0;
  out.framesSkipped = nf - finite;
  m_note = "frame backgrounds on " + name() + ": upload " + ms(upload) + ", meshes " + ms(sep.meshSeconds) +
           ", filter and splines on the host " + ms(sep.hostSeconds) + ", subtraction " +
           ms(sep.subtractSeconds) + ", download " + ms(down) +
           "; frames kept on the device for the global background, hot pixels and prefetch";
  progress.report(1.0, "frame backgrounds (GPU)");
  return out;
}

}  // namespace st::gpu

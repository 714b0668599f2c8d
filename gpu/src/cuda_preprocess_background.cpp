// CudaPreprocess: the per-pixel background (stats::subtractPixelBackground) on the device; the cube
// prefetched behind the CPU stages when it is the same one.
#include <algorithm>
#include <cmath>
#include <memory>

#include "cuda_preprocess.hpp"
#include "global_background_host.hpp"
#include "preprocess_params.hpp"
#include "resident_cube.hpp"
#include "st/common/error.hpp"

namespace st::gpu {

using namespace preprocess_detail;

stats::Background CudaPreprocess::subtractPixelBackground(FrameCube& cube,
                                                          const stats::BackgroundParams& params,
                                                          const detect::MovingMask* exclude,
                                                          ProgressSink& progress, CancelToken& cancel) {
  return pixelBackground(cube, params, exclude, progress, cancel, nullptr);
}

stats::Background CudaPreprocess::pixelBackground(FrameCube& cube, const stats::BackgroundParams& params,
                                                  const detect::MovingMask* exclude, ProgressSink& progress,
                                                  CancelToken& cancel, KeptCube* keep) {
  finishHostCopies();
  m_phase.reset();         // the sky rate's phase-correlation buffers: not needed from here
  m_registration.reset();  // nor registration's
  Stopwatch sw;
  const int w = cube.width(), h = cube.height();
  const std::size_t nf = cube.frameCount(), np = cube.framePixels();
  if (exclude && !exclude->empty() && exclude->frameCount() != nf)
    throw GpuError("the exclusion mask has " + std::to_string(exclude->frameCount()) + " frames, the cube " +
                   std::to_string(nf));
  stats::Background out;
  // The clip's evenly spaced frames and frame n's window of them: stats::pixelBackgroundWindows, exactly what
  // the CPU's subtractPixelBackground and the co-moving fit's model (FitOptions::selfSubtraction) take.
  const std::vector<double> t = cube.timeOffsetsS();
  const stats::PixelBackgroundWindows windows = stats::pixelBackgroundWindows(cube, params);
  const std::vector<std::size_t>& frames = windows.frames;
  out.framesUsed = frames.size();
  const std::size_t nk = frames.size();
  std::vector<int> lo(nf, 0), hi(nf, 0);
  for (std::size_t n = 0; n < nf; ++n) {
    const auto [a, b] = windows.window(n, t);
    lo[n] = static_cast<int>(a);
    hi[n] = static_cast<int>(b);
  }
  const double hostTables = sw.lap();
  ST_CUDA_CHECK(cudaSetDevice(m_device.ordinal));
  DeviceResources& r = resources();
  cudaStream_t s = r.compute.get();
  // The cube (and its mask) uploaded by prefetch() behind the CPU stages, when it is this one unchanged.
  const std::shared_ptr<Prefetch> pf = std::move(m_prefetch);
  if (pf) pf->join();
  const bool prefetched = pf && pf->ok && pf->data == cube.pixels().data() && pf->size == nf * np &&
                          pf->maskSize == cube.mask().size() &&
                          pf->key == (pf->shapeKeyOnly ? cubeShapeKey(cube) : cubeKey(cube));
  DeviceBuffer<float> pix = prefetched ? std::move(pf->pix) : DeviceBuffer<float>(nf * np);
  DeviceBuffer<std::uint8_t> mask;
  if (prefetched)
    mask = std::move(pf->mask);
  else if (!cube.mask().empty())
    mask = toDevice(cube.mask());
  DeviceBuffer<float> buf(nk * np), level(np), sigma(np);
  DeviceBuffer<double> hiBuf(np);
  DeviceBuffer<std::uint8_t> valid(np);
  std::vector<int> used(frames.begin(), frames.end());
  DeviceBuffer<int> usedD = toDevice(used), loD = toDevice(lo), hiD = toDevice(hi);
  DeviceBuffer<std::uint8_t> canvas;
  DeviceBuffer<int> csx, csy;
  BackgroundLaunch p{};
  if (exclude && !exclude->empty()) {
    canvas = toDevice(exclude->canvas());
    std::vector<int> sx(nf), sy(nf);
    for (std::size_t n = 0; n < nf; ++n) {
      sx[n] = exclude->shiftX(n);
      sy[n] = exclude->shiftY(n);
    }
    csx = toDevice(sx);
    csy = toDevice(sy);
    p.canvas = canvas.get();
    p.canvasShiftX = csx.get();
    p.canvasShiftY = csy.get();
    p.canvasX0 = exclude->x0();
    p.canvasY0 = exclude->y0();
    p.canvasW = exclude->canvasWidth();
    p.canvasH = exclude->canvasHeight();
  }
  if (!prefetched) {
    Uploader up(r, cube.pixels().data(), np);
    up.upload(pix.get(), 0, static_cast<int>(nf), r.copy.get());
    r.copy.sync();
  }
  const double upload = sw.lap();
  // The global background (first estimate and strong-signal level) from the uploaded cube.
  out.global =
      globalBackgroundOnDevice(cube, pix.get(), cube.mask().empty() ? nullptr : mask.get(), params.global, s);
  const double global = sw.lap();
  progress.report(0.2, "per-pixel background (GPU)");
  cancel.throwIfCancelled();
  p.pix = pix.get();
  p.mask = cube.mask().empty() ? nullptr : mask.get();
  p.buf = buf.get();
  p.usedFrames = usedD.get();
  p.width = w;
  p.height = h;
  p.nf = static_cast<int>(nf);
  p.nk = static_cast<int>(nk);
  p.strongOffset = params.strongSignalXi * out.global.sigma;
  p.xi = params.xi;
  p.minSamples = params.minSamples;
  p.globalMean = out.global.mean;
  p.globalSigma = out.global.sigma;
  p.level = level.get();
  p.sigma = sigma.get();
  p.valid = valid.get();
  p.hi = hiBuf.get();
  p.winLo = loD.get();
  p.winHi = hiD.get();
  p.window = windows.windowS > 0.0 ? 1 : 0;
  Event k0(true), k1(true), kc(true), k2(true), k3(true);
  k0.record(s);
  launchBackgroundPrepare(p, s);
  k1.record(s);
  launchBackgroundStrongCut(p, s);
  kc.record(s);
  launchBackgroundClip(p, s);
  k2.record(s);
  r.compute.sync();
  cancel.throwIfCancelled();
  progress.report(0.5, "per-pixel background (GPU)");
  launchBackgroundSubtract(p, s);
  k3.record(s);
  out.level = Image(w, h);
  out.sigma = Image(w, h);
  std::vector<std::uint8_t> ok(np);
  ST_CUDA_CHECK(cudaMemcpyAsync(out.level.data(), level.get(), np * 4, cudaMemcpyDeviceToHost, s));
  ST_CUDA_CHECK(cudaMemcpyAsync(out.sigma.data(), sigma.get(), np * 4, cudaMemcpyDeviceToHost, s));
  ST_CUDA_CHECK(cudaMemcpyAsync(ok.data(), valid.get(), np, cudaMemcpyDeviceToHost, s));
  r.compute.sync();
  const double kernels = sw.lap();
  double sumVar = 0.0;
  std::size_t nValid = 0;
  for (std::size_t i = 0; i < np; ++i) {
    if (!ok[i]) continue;
    sumVar += static_cast<double>(out.sigma.pixels[i]) * out.sigma.pixels[i];
    ++nValid;
  }
  if (nValid == 0) {
    throw InputError("per-pixel background: no pixel has " + std::to_string(params.minSamples) +
                     " unmasked background samples (frames used: " + std::to_string(nk) + ")");
  }
  cancel.throwIfCancelled();
  // Every kernel succeeded: the host cube is written now (unless the frames stay on the device).
  if (!keep) download(r, cube.pixels().data(), pix.get(), nf * np * sizeof(float), s);
  const double down = sw.lap();
  out.pixelsFilled = np - nValid;
  out.filled.resize(np);
  for (std::size_t i = 0; i < np; ++i)
    out.filled[i] = !ok[i];
  out.sigmaN = std::sqrt(sumVar / static_cast<double>(nValid));
  if (params.noiseMap) out.noiseMap = stats::boxSmooth(out.sigma, params.noiseMapBoxPx, ok);
  const double host = sw.lap();
  m_note = "per-pixel background on " + name() + ": tables " + ms(hostTables) + ", upload " +
           (prefetched ? std::string(pf->keptFrames ? "none (the frame backgrounds' frames; mask "
                                                    : "prefetched behind the CPU stages (") +
                             ms(pf->seconds) + " on its thread; waited " + ms(upload) + ")"
                       : ms(upload)) +
           ", global background " + ms(global) + " (" + std::to_string(out.global.iterations) +
           " passes), kernels " + ms(kernels) + " (prepare " + ms(Event::elapsed(k0, k1)) + ", strong cut " +
           ms(Event::elapsed(k1, kc)) + ", clip " + ms(Event::elapsed(kc, k2)) + ", subtract " +
           ms(Event::elapsed(k2, k3)) + "), download " +
           (keep ? std::string("kept on the device") : ms(down)) + ", host " + ms(host);
  if (keep) {
    keep->pix = std::move(pix);
    keep->sigma = std::move(sigma);
    keep->hasMask = !cube.mask().empty();
    keep->mask = std::move(mask);
  }
  progress.report(1.0, "per-pixel background (GPU)");
  return out;
}

}  // namespace st::gpu

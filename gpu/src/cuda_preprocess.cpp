// The CUDA pre-processing accelerator (gpu/include/st/gpu/preprocess.hpp). Host side: the CPU's tables
// (frames used, windows, weights) are made here exactly as core makes them, the kernels
// (preprocess_kernels.cu) do the per-pixel and per-frame work, and the host cube is written only after every
// kernel has succeeded, so a st::GpuError leaves it as it was (the caller falls back to the CPU).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <exception>
#include <memory>
#include <mutex>
#include <thread>

#include "cuda_check.hpp"
#include "device_info.hpp"
#include "global_background_host.hpp"
#include "host_buffer.hpp"
#include "preprocess_params.hpp"
#include "residual_means_host.hpp"
#include "resident_cube.hpp"
#include "st/common/error.hpp"
#include "st/common/parallel.hpp"
#include "st/gpu/preprocess.hpp"
#include "uploader.hpp"
#include "zero_bias.hpp"
#include "zero_bias_kernels.hpp"

namespace st::gpu {
namespace {

template <class T>
std::vector<T> toHost(const DeviceBuffer<T>& d, std::size_t count) {
  std::vector<T> out(count);
  if (count) ST_CUDA_CHECK(cudaMemcpy(out.data(), d.get(), count * sizeof(T), cudaMemcpyDeviceToHost));
  return out;
}

// stats/background.cpp evenlySpaced.
std::vector<std::size_t> evenlySpaced(std::size_t total, std::size_t wanted) {
  std::vector<std::size_t> idx;
  if (total == 0) return idx;
  const std::size_t n = std::min(total, std::max<std::size_t>(1, wanted));
  for (std::size_t i = 0; i < n; ++i)
    idx.push_back(n == total ? i : (i * total) / n);
  return idx;
}

/// Device -> pageable host through the two pinned staging buffers (the host copy of one piece on every
/// core while the next piece's DMA runs).
void download(DeviceResources& r, void* host, const void* dev, std::size_t bytes, cudaStream_t s) {
  r.copy.sync();  // the staging buffers may still feed an upload
  const std::size_t piece = kStagingBytes;
  const std::size_t pieces = (bytes + piece - 1) / piece;
  Event ready[2];
  auto enqueue = [&](std::size_t p) {
    const std::size_t off = p * piece, len = std::min(piece, bytes - off);
    ST_CUDA_CHECK(cudaMemcpyAsync(r.staging[p & 1].get(), static_cast<const char*>(dev) + off, len,
                                  cudaMemcpyDeviceToHost, s));
    ready[p & 1].record(s);
  };
  if (pieces > 0) enqueue(0);
  for (std::size_t p = 0; p < pieces; ++p) {
    if (p + 1 < pieces) enqueue(p + 1);
    ready[p & 1].sync();
    const std::size_t off = p * piece, len = std::min(piece, bytes - off);
    char* dst = static_cast<char*>(host) + off;
    const char* src = static_cast<const char*>(r.staging[p & 1].get());
    parallelFor(len, std::size_t{1} << 21,
                [&](std::size_t lo, std::size_t hi) { std::memcpy(dst + lo, src + lo, hi - lo); });
  }
}

class Stopwatch {
 public:
  double lap() {
    const auto now = std::chrono::steady_clock::now();
    const double s = std::chrono::duration<double>(now - m_last).count();
    m_last = now;
    return s;
  }

 private:
  std::chrono::steady_clock::time_point m_last = std::chrono::steady_clock::now();
};

std::string ms(double s) {
  char text[32];
  std::snprintf(text, sizeof text, "%.1f ms", s * 1e3);
  return text;
}

/// Benchmark knob: ST_GPU_STAGEWISE=1 runs the pre-processing as before the resident zero-biased cube (the
/// cube uploaded and downloaded by the per-pixel background and again by the residual means, star
/// subtraction, zeroing and the noise model on the CPU, no prefetch), for before/after figures from one
/// binary.
bool stagewise() {
  const char* e = std::getenv("ST_GPU_STAGEWISE");
  return e && *e && *e != '0';
}

class CudaPreprocess final : public CudaPreprocessAccelerator {
 public:
  explicit CudaPreprocess(DeviceInfo device) : m_device(std::move(device)) {}

  [[nodiscard]] std::string name() const override { return "cuda: " + m_device.name; }
  [[nodiscard]] std::string lastNote() const override { return m_note; }  // the last stage's
  void setKeepResident(bool keep) override { m_keepResident = keep; }

  stats::ClipStats globalBackground(const FrameCube& cube,
                                    const stats::GlobalBackgroundParams& params) override {
    ST_CUDA_CHECK(cudaSetDevice(m_device.ordinal));
    DeviceResources& r = ensureResources(m_res);
    return globalBackgroundUploaded(cube, params, r.compute.get());
  }

  double removeResidualMeans(FrameCube& cube, int meshPx, double clipSigma, ProgressSink& progress,
                             CancelToken& cancel) override {
    Stopwatch sw;
    const std::size_t nf = cube.frameCount(), np = cube.framePixels();
    ST_CUDA_CHECK(cudaSetDevice(m_device.ordinal));
    DeviceResources& r = ensureResources(m_res);
    m_kept = DeviceBuffer<float>();
    m_keptData = nullptr;
    DeviceBuffer<float> pix(nf * np);
    Uploader up(r, cube.pixels().data(), np);
    up.upload(pix.get(), 0, static_cast<int>(nf), r.copy.get());
    r.copy.sync();
    const double upload = sw.lap();
    cancel.throwIfCancelled();
    progress.report(0.3, "residual means (GPU)");
    const double rms = removeResidualMeansOnDevice(pix.get(), cube.width(), cube.height(),
                                                   static_cast<int>(nf), meshPx, clipSigma, r.compute.get());
    const double kernels = sw.lap();
    cancel.throwIfCancelled();
    // Every kernel succeeded: the host cube is written now.
    download(r, cube.pixels().data(), pix.get(), nf * np * sizeof(float), r.compute.get());
    const double down = sw.lap();
    m_kept = std::move(pix);
    m_keptData = cube.pixels().data();
    m_keptKey = cubeKey(cube);
    m_note = "residual means on " + name() + ": upload " + ms(upload) + ", kernels and host fill " +
             ms(kernels) + ", download " + ms(down) + "; frames kept on the device for the matched filter";
    progress.report(1.0, "residual means (GPU)");
    return rms;
  }

  std::shared_ptr<void> prefetch(const FrameCube& cube) override {
    if (stagewise()) return nullptr;
    if (m_prefetch) m_prefetch->join();
    auto p = std::make_shared<Prefetch>();
    p->data = cube.pixels().data();
    p->size = cube.pixels().size();
    p->maskSize = cube.mask().size();
    p->key = cubeKey(cube);
    const std::uint8_t* maskData = cube.mask().data();
    // One thread, one core: the host copies into the pinned staging buffers (~10 GB/s) run beside the
    // CPU stages (static sources, PSF: ~1 s) instead of on every core at the per-pixel background.
    p->thread = std::jthread([this, q = p.get(), maskData] {
      try {
        Stopwatch sw;
        ST_CUDA_CHECK(cudaSetDevice(m_device.ordinal));
        DeviceResources& r = ensureResources(m_prefetchRes);
        q->pix = DeviceBuffer<float>(q->size);
        if (q->maskSize) q->mask = DeviceBuffer<std::uint8_t>(q->maskSize);
        stagedUpload(r, q->pix.get(), q->data, q->size * sizeof(float));
        if (q->maskSize) stagedUpload(r, q->mask.get(), maskData, q->maskSize);
        r.copy.sync();
        q->seconds = sw.lap();
        q->ok = true;
      } catch (const std::exception&) {
        q->ok = false;  // the per-pixel background uploads the cube itself
      }
    });
    m_prefetch = p;
    // The guard joins the upload's thread when the pipeline lets it go (before its cube is freed).
    // Unused by then (the pipeline stopped before its per-pixel background: cancelled, an error), its device
    // copy is freed rather than held until the next prefetch.
    return std::shared_ptr<void>(static_cast<void*>(p.get()), [p](void*) {
      p->join();
      p->ok = false;
      p->pix = DeviceBuffer<float>();
      p->mask = DeviceBuffer<std::uint8_t>();
    });
  }

  stats::NoiseModel estimateNoiseModel(const FrameCube& zeroBiased, const Image& pixelSigma,
                                       const std::vector<std::uint8_t>& unmeasured,
                                       const stats::NoiseModelParams& params, CancelToken& cancel) override {
    if (stagewise()) {
      m_note.clear();
      return stats::estimateNoiseModel(zeroBiased, pixelSigma, unmeasured, params, cancel);
    }
    Stopwatch sw;
    const int w = zeroBiased.width(), h = zeroBiased.height();
    const std::size_t nf = zeroBiased.frameCount(), np = zeroBiased.framePixels();
    // The variance map and the reference sigma before the frame scales: the CPU's own function on a cube of
    // no frames (its frame-scale loop is then empty and the typical scale 1).
    const FrameCube shape(w, h, 0);
    stats::NoiseModel m = stats::estimateNoiseModel(shape, pixelSigma, unmeasured, params, cancel);
    const double hostMap = sw.lap();
    ST_CUDA_CHECK(cudaSetDevice(m_device.ordinal));
    DeviceResources& r = ensureResources(m_res);
    cudaStream_t s = r.compute.get();
    // The frames zeroBias or removeResidualMeans left on the device, when this is that cube unchanged.
    const bool kept = m_kept.size() == nf * np && m_keptData == zeroBiased.pixels().data() &&
                      m_keptKey == cubeKey(zeroBiased);
    DeviceBuffer<float> uploaded;
    const float* pix = m_kept.get();
    if (!kept) {
      uploaded = DeviceBuffer<float>(std::max<std::size_t>(1, nf * np));
      Uploader up(r, zeroBiased.pixels().data(), np);
      up.upload(uploaded.get(), 0, static_cast<int>(nf), r.copy.get());
      r.copy.sync();
      pix = uploaded.get();
    }
    const double upload = sw.lap();
    DeviceBuffer<float> var = toDevice(m.variance.pixels);
    DeviceBuffer<double> med(std::max<std::size_t>(1, nf));
    DeviceBuffer<unsigned> cnt(std::max<std::size_t>(1, nf));
    launchFrameMedians(pix, var.get(), np, static_cast<int>(nf), std::max(1, params.sampleStride), med.get(),
                       cnt.get(), s);
    ST_CUDA_CHECK(cudaStreamSynchronize(s));
    const std::vector<double> medians = toHost(med, nf);
    const std::vector<unsigned> counts = toHost(cnt, nf);
    const double kernels = sw.lap();
    cancel.throwIfCancelled();
    // stats::estimateNoiseModel's frame scales from the medians (kChi2OneMedian: the median of chi^2 with
    // one degree of freedom), the typical one for frames without 100 values.
    constexpr double kChi2OneMedian = 0.454936423119572;
    m.frameScale.assign(nf, std::nan(""));
    for (std::size_t n = 0; n < nf; ++n)
      if (counts[n] >= 100) m.frameScale[n] = std::sqrt(medians[n] / kChi2OneMedian);
    std::vector<double> scales;
    for (double v : m.frameScale)
      if (std::isfinite(v) && v > 0.0) scales.push_back(v);
    double typical = 1.0;
    if (!scales.empty()) {
      const auto mid = scales.begin() + static_cast<std::ptrdiff_t>(scales.size() / 2);
      std::nth_element(scales.begin(), mid, scales.end());
      typical = *mid;
    }
    for (double& v : m.frameScale)
      if (!(std::isfinite(v) && v > 0.0)) v = typical;
    m.sigmaRef *= typical;
    m_note = "noise model on " + name() + ": variance map on the host " + ms(hostMap) + ", " +
             (kept ? "frames already on the device" : "upload " + ms(upload)) + ", frame medians " +
             ms(kernels);
    return m;
  }

  stats::Background subtractPixelBackground(FrameCube& cube, const stats::BackgroundParams& params,
                                            const detect::MovingMask* exclude, ProgressSink& progress,
                                            CancelToken& cancel) override {
    return pixelBackground(cube, params, exclude, progress, cancel, nullptr);
  }

  bool zeroBias(FrameCube& cube, const pipeline::ZeroBiasInputs& in, pipeline::ZeroBiasResult& out,
                ProgressSink& progress, CancelToken& cancel) override {
    if (stagewise()) return false;
    const int w = cube.width(), h = cube.height();
    const std::size_t nf = cube.frameCount(), np = cube.framePixels();
    Stopwatch sw;
    auto lap = [&](const char* stage) { out.stageSeconds.emplace_back(stage, sw.lap()); };
    KeptCube kc;
    {
      SubProgress sub(progress, 0.4, 0.65);
      out.background = pixelBackground(cube, in.background, in.exclude, sub, cancel, &kc);
    }
    const std::string bgNote = m_note;
    lap("per-pixel background");
    ST_CUDA_CHECK(cudaSetDevice(m_device.ordinal));
    DeviceResources& r = ensureResources(m_res);
    cudaStream_t s = r.compute.get();
    const DeviceCubeRef d{kc.pix.get(), kc.hasMask ? kc.mask.get() : nullptr, w, h, static_cast<int>(nf)};
    const float* sigma = out.background.sigma.size() == np ? kc.sigma.get() : nullptr;
    out.starsAttempted = in.subtractRegion && !in.subtractRegion->empty();
    std::string starTiming;
    if (out.starsAttempted) {
      cancel.throwIfCancelled();
      out.starSubtraction = subtractStarTemplateOnDevice(cube, d, *in.subtractRegion, sigma,
                                                         in.starSubtraction, s, &starTiming);
      if (out.starSubtraction.applied && in.starMask) {
        const MovingMask& ex = out.starSubtraction.excess;
        const auto& c = ex.canvas();
        for (std::size_t i = 0; i < c.size(); ++i)
          if (c[i])
            in.starMask->set(ex.x0() + static_cast<int>(i) % ex.canvasWidth(),
                             ex.y0() + static_cast<int>(i) / ex.canvasWidth());
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
    if (in.removeResidualMean)
      out.residualMeanRms = removeResidualMeansOnDevice(kc.pix.get(), w, h, static_cast<int>(nf),
                                                        in.residualMeshPx, in.residualClipSigma, s);
    ST_CUDA_CHECK(cudaStreamSynchronize(s));
    const double rmKernels = rm.lap();
    cancel.throwIfCancelled();
    // Every kernel succeeded: the host cube is written now, and the frames kept for the matched filter.
    m_kept = DeviceBuffer<float>();
    m_keptData = nullptr;
    download(r, cube.pixels().data(), kc.pix.get(), nf * np * sizeof(float), s);
    const double down = rm.lap();
    m_kept = std::move(kc.pix);
    m_keptData = cube.pixels().data();
    m_keptKey = cubeKey(cube);
    progress.report(0.83, "residual means (GPU)");
    lap("residual means");
    std::string stages;
    for (const auto& [stage, sec] : out.stageSeconds)
      stages += (stages.empty() ? "" : ", ") + stage + " " + ms(sec);
    m_note = "per-pixel background to residual means on " + name() +
             ", the cube kept on the device: " + stages + " (residual means kernels " + ms(rmKernels) +
             ", download " + ms(down) + "; frames kept for the matched filter); star subtraction: " +
             (starTiming.empty() ? "none" : starTiming) + "; " + bgNote;
    return true;
  }

 private:
  /// The device buffers the per-pixel background leaves for zeroBias's next stages.
  struct KeptCube {
    DeviceBuffer<float> pix, sigma;
    DeviceBuffer<std::uint8_t> mask;
    bool hasMask = false;
  };

  /// stats::subtractPixelBackground; with `keep`, the zero-biased frames (and the mask and sigma) stay on
  /// the device in *keep and the host cube is not written.
  stats::Background pixelBackground(FrameCube& cube, const stats::BackgroundParams& params,
                                    const detect::MovingMask* exclude, ProgressSink& progress,
                                    CancelToken& cancel, KeptCube* keep) {
    Stopwatch sw;
    const int w = cube.width(), h = cube.height();
    const std::size_t nf = cube.frameCount(), np = cube.framePixels();
    if (exclude && !exclude->empty() && exclude->frameCount() != nf)
      throw GpuError("the exclusion mask has " + std::to_string(exclude->frameCount()) +
                     " frames, the cube " + std::to_string(nf));
    stats::Background out;
    const std::vector<std::size_t> frames = evenlySpaced(nf, params.maxFrames);
    out.framesUsed = frames.size();
    const std::size_t nk = frames.size();
    // Frame n's window of used frames (stats::subtractPixelBackground).
    const std::vector<double> t = cube.timeOffsetsS();
    const bool sorted = std::is_sorted(t.begin(), t.end());
    const double window = sorted ? params.moverWindowFraction * cube.timeSpanS() : 0.0;
    std::vector<int> lo(nf, 0), hi(nf, 0);
    if (window > 0.0) {
      for (std::size_t n = 0; n < nf; ++n) {
        lo[n] = static_cast<int>(
            std::lower_bound(frames.begin(), frames.end(), n,
                             [&](std::size_t k, std::size_t m) { return t[k] < t[m] - window; }) -
            frames.begin());
        hi[n] = static_cast<int>(
            std::upper_bound(frames.begin(), frames.end(), n,
                             [&](std::size_t m, std::size_t k) { return t[m] + window < t[k]; }) -
            frames.begin());
      }
    }
    const double hostTables = sw.lap();
    ST_CUDA_CHECK(cudaSetDevice(m_device.ordinal));
    DeviceResources& r = ensureResources(m_res);
    cudaStream_t s = r.compute.get();
    // The cube (and its mask) uploaded by prefetch() behind the CPU stages, when it is this one unchanged.
    const std::shared_ptr<Prefetch> pf = std::move(m_prefetch);
    if (pf) pf->join();
    const bool prefetched = pf && pf->ok && pf->data == cube.pixels().data() && pf->size == nf * np &&
                            pf->maskSize == cube.mask().size() && pf->key == cubeKey(cube);
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
    out.global = globalBackgroundOnDevice(cube, pix.get(), cube.mask().empty() ? nullptr : mask.get(),
                                          params.global, s);
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
    p.strong = out.global.mean + params.strongSignalXi * out.global.sigma;
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
    p.window = window > 0.0 ? 1 : 0;
    Event k0(true), k1(true), k2(true), k3(true);
    k0.record(s);
    launchBackgroundPrepare(p, s);
    k1.record(s);
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
             (prefetched ? "prefetched behind the CPU stages (" + ms(pf->seconds) +
                               " on its thread; waited " + ms(upload) + ")"
                         : ms(upload)) +
             ", global background " + ms(global) + " (" + std::to_string(out.global.iterations) +
             " passes), kernels " + ms(kernels) + " (prepare " + ms(Event::elapsed(k0, k1)) + ", clip " +
             ms(Event::elapsed(k1, k2)) + ", subtract " + ms(Event::elapsed(k2, k3)) + "), download " +
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

 public:
  stack::MatchedFilterResult filterCube(FrameCube& cube, const stack::FilterKernel& kernel,
                                        ProgressSink& progress, CancelToken& cancel,
                                        const stats::NoiseModel* noise, std::uint64_t revision) override {
    const bool hasMask = cube.mask().size() == cube.pixels().size();
    return filter(cube, hasMask, cube, false, kernel, progress, cancel, noise, revision);
  }

  stack::MatchedFilterResult filterCubeFrom(const FrameCube& source, FrameCube& filtered,
                                            const stack::FilterKernel& kernel, ProgressSink& progress,
                                            CancelToken& cancel, const stats::NoiseModel* noise,
                                            std::uint64_t revision) override {
    filtered.mask().clear();
    // A destination of the right size (the pipeline allocates it while the stages before run) is used as it
    // is; else it is allocated here, on another thread while the device works.
    const bool allocate = filtered.pixels().size() != source.pixels().size();
    return filter(source, false, filtered, allocate, kernel, progress, cancel, noise, revision);
  }

 private:
  /// The matched filter of `cube`'s pixels (with its mask when `hasMask`) written into `dest` (which may be
  /// `cube`); `freshDest`: dest's pixels are (re)allocated here, on another thread while the device works.
  stack::MatchedFilterResult filter(const FrameCube& cube, bool hasMask, FrameCube& dest, bool freshDest,
                                    const stack::FilterKernel& kernel, ProgressSink& progress,
                                    CancelToken& cancel, const stats::NoiseModel* noise,
                                    std::uint64_t revision) {
    Stopwatch sw;
    const int w = cube.width(), h = cube.height();
    const std::size_t nf = cube.frameCount(), np = cube.framePixels();
    const bool weighted = noise && !noise->empty();
    const int half = kernel.halfSize;
    if (half > kMaxFilterHalf)
      throw GpuError("matched-filter kernel of half size " + std::to_string(half) + " px (at most " +
                     std::to_string(kMaxFilterHalf) + " on the GPU)");
    if (weighted &&
        (noise->variance.width != w || noise->variance.height != h || noise->frameScale.size() != nf))
      throw InputError("matched filter: the noise model (" + std::to_string(noise->variance.width) + "x" +
                       std::to_string(noise->variance.height) + ", " +
                       std::to_string(noise->frameScale.size()) + " frames) does not match the cube (" +
                       std::to_string(w) + "x" + std::to_string(h) + ", " + std::to_string(nf) + " frames)");
    ST_CUDA_CHECK(cudaSetDevice(m_device.ordinal));
    DeviceResources& r = ensureResources(m_res);
    cudaStream_t s = r.compute.get();
    progress.report(0.0, "matched filter (GPU)");
    // The destination's pages are faulted in on other cores while the device uploads and filters.
    std::vector<float> destPixels;
    std::jthread allocate;
    std::exception_ptr allocError;
    if (freshDest) {
      allocate = std::jthread([&destPixels, &allocError, n = nf * np] {
        try {
          destPixels = prefaultedFloats(n);
        } catch (...) {
          allocError = std::current_exception();  // rethrown on this thread after the join
        }
      });
    }
    // The frames removeResidualMeans left on the device, when this is that cube unchanged: no upload.
    DeviceBuffer<float> in = std::move(m_kept);
    const bool kept =
        !hasMask && in.size() == nf * np && m_keptData == cube.pixels().data() && m_keptKey == cubeKey(cube);
    m_keptData = nullptr;
    if (!kept) {
      in = DeviceBuffer<float>();  // another cube's: freed first
      in = DeviceBuffer<float>(nf * np);
    }
    DeviceBuffer<float> out(nf * np);
    DeviceBuffer<std::uint8_t> mask;
    if (hasMask) mask = toDevice(cube.mask());
    if (!kept) {
      Uploader up(r, cube.pixels().data(), np);
      up.upload(in.get(), 0, static_cast<int>(nf), r.copy.get());
      r.copy.sync();
    }
    const double upload = sw.lap();
    FilterLaunch p{};
    p.in = in.get();
    p.mask = hasMask ? mask.get() : nullptr;
    p.width = w;
    p.height = h;
    p.half = half;
    DeviceBuffer<float> invVarD, invS2D, outScaleD;
    Event k0(true), k1(true), k2(true);
    k0.record(s);
    if (weighted) {
      std::vector<float> invVar(np);
      for (std::size_t i = 0; i < np; ++i) {
        const float v = noise->variance.pixels[i];
        invVar[i] = v > 0.0f && std::isfinite(v) ? 1.0f / v : 0.0f;
      }
      std::vector<double> invS2(nf);
      std::vector<float> invS2f(nf);
      for (std::size_t n = 0; n < nf; ++n) {
        invS2[n] = 1.0 / (noise->frameScale[n] * noise->frameScale[n]);
        invS2f[n] = static_cast<float>(invS2[n]);
      }
      invVarD = toDevice(invVar);
      invS2D = toDevice(invS2f);
      DeviceBuffer<double> invS2d = toDevice(invS2);
      DeviceBuffer<float> omega(np), phi(np);
      launchOmega(in.get(), p.mask, invS2d.get(), invVarD.get(), omega.get(), w, h, static_cast<int>(nf), s);
      std::vector<float> k2v(kernel.kernel.pixels.size());
      for (std::size_t i = 0; i < k2v.size(); ++i)
        k2v[i] = kernel.kernel.pixels[i] * kernel.kernel.pixels[i];
      setFilterKernel(k2v.data(), half, s);
      FilterLaunch q = p;
      q.in = omega.get();
      q.mask = nullptr;
      q.out = phi.get();
      q.f0 = 0;
      q.f1 = 1;
      launchFilter(q, s);
      std::vector<float> phiH(np);
      ST_CUDA_CHECK(cudaMemcpyAsync(phiH.data(), phi.get(), np * 4, cudaMemcpyDeviceToHost, s));
      r.compute.sync();
      double phiMax = 0.0;
      for (float v : phiH)
        phiMax = std::max(phiMax, static_cast<double>(v));
      const double scale = noise->sigmaRef * std::sqrt(kernel.sumSquares);
      std::vector<float> outScale(np);
      for (std::size_t i = 0; i < np; ++i) {
        const double v = phiH[i];
        outScale[i] = v > 1e-9 * phiMax ? static_cast<float>(scale / std::sqrt(v)) : 0.0f;
      }
      outScaleD = toDevice(outScale);
      p.invVar = invVarD.get();
      p.invS2 = invS2D.get();
      p.outScale = outScaleD.get();
    }
    k1.record(s);
    setFilterKernel(kernel.kernel.data(), half, s);
    p.out = out.get();
    constexpr int kFramesPerLaunch = 128;
    for (std::size_t f0 = 0; f0 < nf; f0 += kFramesPerLaunch) {
      p.f0 = static_cast<int>(f0);
      p.f1 = static_cast<int>(std::min(nf, f0 + kFramesPerLaunch));
      launchFilter(p, s);
      if (f0 % (4 * kFramesPerLaunch) == 0) {
        r.compute.sync();
        cancel.throwIfCancelled();
        progress.report(0.1 + 0.7 * static_cast<double>(p.f1) / nf, "matched filter (GPU)");
      }
    }
    k2.record(s);
    // sigma_F from the samples of up to 64 frames (stack::filterCube).
    const std::vector<std::size_t> sampleFrames = stack::filterNoiseFrames(nf);
    const int nx = w - 2 * half > 0 ? (w - 2 * half + 2) / 3 : 0;
    const int ny = h - 2 * half > 0 ? (h - 2 * half + 2) / 3 : 0;
    const std::size_t perFrame = static_cast<std::size_t>(nx) * ny;
    DeviceBuffer<float> samplesD(std::max<std::size_t>(1, perFrame * sampleFrames.size()));
    if (perFrame > 0)
      for (std::size_t k = 0; k < sampleFrames.size(); ++k)
        launchNoiseSamples(in.get(), p.mask, out.get(), w, h, static_cast<int>(sampleFrames[k]), half,
                           samplesD.get() + k * perFrame, nx, ny, s);
    std::vector<float> samplesH(perFrame * sampleFrames.size());
    if (!samplesH.empty())
      ST_CUDA_CHECK(
          cudaMemcpyAsync(samplesH.data(), samplesD.get(), samplesH.size() * 4, cudaMemcpyDeviceToHost, s));
    r.compute.sync();
    const double kernels = sw.lap();
    std::vector<std::vector<float>> samples(sampleFrames.size());
    for (std::size_t k = 0; k < sampleFrames.size(); ++k)
      for (std::size_t i = 0; i < perFrame; ++i) {
        const float v = samplesH[k * perFrame + i];
        if (!std::isnan(v)) samples[k].push_back(v);
      }
    stack::MatchedFilterResult result = stack::filterNoiseFromSamples(samples, kernel);
    cancel.throwIfCancelled();
    in = DeviceBuffer<float>();
    double waitAlloc = 0.0;
    if (freshDest) {
      allocate.join();
      if (allocError) std::rethrow_exception(allocError);
      waitAlloc = sw.lap();
      download(r, destPixels.data(), out.get(), nf * np * sizeof(float), s);
      dest.pixels() = std::move(destPixels);
    } else {
      download(r, dest.pixels().data(), out.get(), nf * np * sizeof(float), s);
    }
    const double down = sw.lap();
    std::string resident = "not kept on the device";
    if (m_keepResident && revision != 0) {
      ResidentSlot& slot = residentSlot(m_device.ordinal);
      std::lock_guard lock(slot.mutex);
      slot.clear();
      slot.cube = std::move(out);
      slot.key = residentKey(dest, revision);
      resident = "kept on the device for the search";
    }
    m_note =
        "matched filter on " + name() + " (" + std::to_string(2 * half + 1) + "^2 kernel" +
        (weighted ? ", weighted" : "") + "): " +
        (kept ? "the residual means' frames on the device (" + ms(upload) + ")" : "upload " + ms(upload)) +
        ", kernels " + ms(kernels) + " (weights " + ms(Event::elapsed(k0, k1)) + ", filter " +
        ms(Event::elapsed(k1, k2)) + ")" +
        (freshDest ? ", waited " + ms(waitAlloc) + " for the host buffer" : std::string()) + ", download " +
        ms(down) + "; filtered cube " + resident;
    progress.report(1.0, "matched filter (GPU)");
    return result;
  }

  DeviceInfo m_device;
  std::unique_ptr<DeviceResources> m_res;
  /// prefetch()'s upload: the cube's identity, and its device copy once `ok`.
  struct Prefetch {
    std::jthread thread;
    DeviceBuffer<float> pix;
    DeviceBuffer<std::uint8_t> mask;
    const float* data = nullptr;
    std::size_t size = 0, maskSize = 0;
    std::uint64_t key = 0;
    bool ok = false;
    double seconds = 0.0;
    void join() {
      if (thread.joinable()) thread.join();
    }
    ~Prefetch() { join(); }
  };
  /// Host -> device through `r`'s pinned staging buffers, the host copies on this thread alone.
  static void stagedUpload(DeviceResources& r, void* dst, const void* src, std::size_t bytes) {
    for (std::size_t off = 0; off < bytes; off += kStagingBytes) {
      const std::size_t len = std::min(kStagingBytes, bytes - off);
      const int b = r.nextStaging;
      r.nextStaging ^= 1;
      r.stagingFree[b].sync();
      std::memcpy(r.staging[b].get(), static_cast<const char*>(src) + off, len);
      ST_CUDA_CHECK(cudaMemcpyAsync(static_cast<char*>(dst) + off, r.staging[b].get(), len,
                                    cudaMemcpyHostToDevice, r.copy.get()));
      r.stagingFree[b].record(r.copy.get());
    }
  }
  std::unique_ptr<DeviceResources> m_prefetchRes;  // its own streams and staging: no contention with m_res
  std::shared_ptr<Prefetch> m_prefetch;            // after m_prefetchRes: joined before that is freed
  std::string m_note;
  bool m_keepResident = true;
  // The frames removeResidualMeans wrote, kept for the matched filter of the same host cube.
  DeviceBuffer<float> m_kept;
  const float* m_keptData = nullptr;
  std::uint64_t m_keptKey = 0;
};

}  // namespace

std::unique_ptr<CudaPreprocessAccelerator> makeCudaPreprocessAccelerator(std::string& whyNot) {
  try {
    std::vector<DeviceInfo> devices = usableDevices(whyNot);
    if (devices.empty()) return nullptr;
    return std::make_unique<CudaPreprocess>(devices.front());
  } catch (const std::exception& e) {
    whyNot = e.what();
    return nullptr;
  }
}

}  // namespace st::gpu

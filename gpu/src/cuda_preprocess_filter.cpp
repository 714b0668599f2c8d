// CudaPreprocess: the (weighted) matched filter (stack::filterCube) on the device; the filtered cube kept
// resident for the search.
#include <algorithm>
#include <cmath>
#include <exception>
#include <mutex>
#include <thread>

#include "cuda_preprocess.hpp"
#include "preprocess_params.hpp"
#include "resident_cube.hpp"
#include "st/common/prefault.hpp"
#include "st/common/error.hpp"

namespace st::gpu {

using namespace preprocess_detail;

stack::MatchedFilterResult CudaPreprocess::filterCube(FrameCube& cube, const stack::FilterKernel& kernel,
                                                      ProgressSink& progress, CancelToken& cancel,
                                                      const stats::NoiseModel* noise,
                                                      std::uint64_t revision) {
  const bool hasMask = cube.mask().size() == cube.pixels().size();
  return finishingCopiesOnError(
      [&] { return filter(cube, hasMask, cube, false, kernel, progress, cancel, noise, revision); });
}

stack::MatchedFilterResult CudaPreprocess::filterCubeFrom(const FrameCube& source, FrameCube& filtered,
                                                          const stack::FilterKernel& kernel,
                                                          ProgressSink& progress, CancelToken& cancel,
                                                          const stats::NoiseModel* noise,
                                                          std::uint64_t revision) {
  filtered.mask().clear();
  // A destination of the right size (the pipeline allocates it while the stages before run) is used as it
  // is; else it is allocated here, on another thread while the device works.
  const bool allocate = filtered.pixels().size() != source.pixels().size();
  return finishingCopiesOnError(
      [&] { return filter(source, false, filtered, allocate, kernel, progress, cancel, noise, revision); });
}

stack::MatchedFilterResult CudaPreprocess::filter(const FrameCube& cube, bool hasMask, FrameCube& dest,
                                                  bool freshDest, const stack::FilterKernel& kernel,
                                                  ProgressSink& progress, CancelToken& cancel,
                                                  const stats::NoiseModel* noise, std::uint64_t revision) {
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
  DeviceResources& r = resources();
  cudaStream_t s = r.compute.get();
  progress.report(0.0, "matched filter (GPU)");
  // The destination's pages are faulted in on other cores while the device uploads and filters.
  PixelVector destPixels;
  std::exception_ptr allocError;  // before the thread: the thread may write it until its join
  std::jthread allocate;
  if (freshDest) {
    allocate = std::jthread([&destPixels, &allocError, n = nf * np] {
      try {
        destPixels = prefaultedPixels(n);  // every value is downloaded into it
      } catch (...) {
        allocError = std::current_exception();  // rethrown on this thread after the join
      }
    });
  }
  // The frames zeroBias or removeResidualMeans left on the device, when this is that cube unchanged (its
  // host copy may still be downloading): no upload.
  const bool kept = !hasMask && keptIs(cube);
  DeviceBuffer<float> uploaded;
  if (!kept) {
    finishHostCopies();  // the host frames are read, and the kept ones (another cube's) freed first
    forgetKept();
    uploaded = DeviceBuffer<float>(nf * np);
  }
  // The kept frames stay in m_kept until the copies are waited for below: the zero-biased cube's download
  // may still read them, also while an exception leaves this function.
  const float* in = kept ? m_kept.get() : uploaded.get();
  DeviceBuffer<float> out(nf * np);
  // Destroyed before `out` (and `uploaded`): on an exception the copies queued from them finish first.
  const HostCopies::DrainOnExit drain(m_copies);
  DeviceBuffer<std::uint8_t> mask;
  if (hasMask) mask = toDevice(cube.mask());
  if (!kept) {
    Uploader up(r, cube.pixels().data(), np);
    up.upload(uploaded.get(), 0, static_cast<int>(nf), r.copy.get());
    r.copy.sync();
  }
  const double upload = sw.lap();
  FilterLaunch p{};
  p.in = in;
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
    // Frames moved onto frame 0's grid cover only part of it (registration): each pixel's weight is averaged
    // over the frames that cover it, as on the CPU (stack::filterCube).
    DeviceBuffer<std::uint32_t> coveringD;
    if (noise->framesCovering.size() == np) coveringD = toDevice(noise->framesCovering);
    DeviceBuffer<float> omega(np), phi(np);
    launchOmega(in, p.mask, invS2d.get(), invVarD.get(), coveringD.get(), omega.get(), w, h,
                static_cast<int>(nf), s);
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
  // Into a host buffer of its own (not the source's, not one still to be allocated), each launch's frames
  // are downloaded behind the next launches.
  const bool behind = !freshDest && &dest != &cube && !syncDownloads();
  const double copiedBefore = m_copies.copySeconds();
  constexpr int kFramesPerLaunch = 128;
  for (std::size_t f0 = 0; f0 < nf; f0 += kFramesPerLaunch) {
    p.f0 = static_cast<int>(f0);
    p.f1 = static_cast<int>(std::min(nf, f0 + kFramesPerLaunch));
    launchFilter(p, s);
    if (behind)
      m_copies.enqueue(dest.pixels().data() + f0 * np, out.get() + f0 * np,
                       static_cast<std::size_t>(p.f1 - p.f0) * np * sizeof(float), s, false,
                       "the matched filter");
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
      launchNoiseSamples(in, p.mask, out.get(), w, h, static_cast<int>(sampleFrames[k]), half,
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
  // The zero-biased cube's download (zeroBias) reads the kept frames, and the filtered frames' go into
  // `dest`.
  const bool queued = m_copies.busy();
  finishHostCopies();
  const double waitCopies = sw.lap();
  forgetKept();
  uploaded = DeviceBuffer<float>();
  double waitAlloc = 0.0;
  if (behind) {
    // downloaded
  } else if (freshDest) {
    allocate.join();
    if (allocError) std::rethrow_exception(allocError);
    waitAlloc = sw.lap();
    download(r, destPixels.data(), out.get(), nf * np * sizeof(float), s);
    dest.pixels() = std::move(destPixels);
  } else if (&dest == &cube) {
    // Filtered in place: the frames half written would be filtered again by the CPU.
    downloadInPlace(r, dest.pixels().data(), out.get(), nf * np * sizeof(float), s, "the matched filter",
                    name());
  } else {
    download(r, dest.pixels().data(), out.get(), nf * np * sizeof(float), s);  // the CPU writes it anew
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
  m_note = "matched filter on " + name() + " (" + std::to_string(2 * half + 1) + "^2 kernel" +
           (weighted ? ", weighted" : "") + "): " +
           (kept ? "the residual means' frames on the device (" + ms(upload) + ")" : "upload " + ms(upload)) +
           ", kernels " + ms(kernels) + " (weights " + ms(Event::elapsed(k0, k1)) + ", filter " +
           ms(Event::elapsed(k1, k2)) +
           (filterRegisterBlocked(half) ? ", 4 outputs a thread" : ", one output a thread") + ")" +
           (freshDest ? ", waited " + ms(waitAlloc) + " for the host buffer" : std::string()) +
           (behind ? ", download behind the launches (" + ms(m_copies.copySeconds() - copiedBefore) +
                         " of copies since the filter began, with the zero-biased cube's), waited " +
                         ms(waitCopies) + " after the kernels"
                   : (queued ? ", waited " + ms(waitCopies) + " for the zero-biased cube's download"
                             : std::string()) +
                         ", download " + ms(down)) +
           "; filtered cube " + resident;
  progress.report(1.0, "matched filter (GPU)");
  return result;
}

}  // namespace st::gpu

// CudaPreprocess: the residual means (stats::removeResidualMeans) and the noise model's frame scales
// (stats::estimateNoiseModel) on the device.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <utility>

#include "cuda_preprocess.hpp"
#include "residual_means_host.hpp"
#include "resident_cube.hpp"
#include "zero_bias_kernels.hpp"

namespace st::gpu {

using namespace preprocess_detail;

double CudaPreprocess::removeResidualMeans(FrameCube& cube, int meshPx, double clipSigma,
                                           ProgressSink& progress, CancelToken& cancel) {
  finishHostCopies();
  Stopwatch sw;
  const std::size_t nf = cube.frameCount(), np = cube.framePixels();
  ST_CUDA_CHECK(cudaSetDevice(m_device.ordinal));
  DeviceResources& r = resources();
  forgetKept();
  DeviceBuffer<float> pix(nf * np);
  Uploader up(r, cube.pixels().data(), np);
  up.upload(pix.get(), 0, static_cast<int>(nf), r.copy.get());
  r.copy.sync();
  const double upload = sw.lap();
  cancel.throwIfCancelled();
  progress.report(0.3, "residual means (GPU)");
  const double rms = removeResidualMeansOnDevice(pix.get(), cube.width(), cube.height(), static_cast<int>(nf),
                                                 meshPx, clipSigma, r.compute.get());
  const double kernels = sw.lap();
  cancel.throwIfCancelled();
  // Every kernel succeeded: the host cube is written now.
  downloadInPlace(r, cube.pixels().data(), pix.get(), nf * np * sizeof(float), r.compute.get(),
                  "the residual means", name());
  const double down = sw.lap();
  m_kept = std::move(pix);
  m_keptData = cube.pixels().data();
  m_keptKey = cubeKey(cube);
  m_note = "residual means on " + name() + ": upload " + ms(upload) + ", kernels and host fill " +
           ms(kernels) + ", download " + ms(down) + "; frames kept on the device for the matched filter";
  progress.report(1.0, "residual means (GPU)");
  return rms;
}

std::uint64_t CudaPreprocess::noiseShapeHash(const Image& pixelSigma,
                                             const std::vector<std::uint8_t>& unmeasured) {
  // FNV-1a over the bytes, 8 at a time.
  std::uint64_t h = 1469598103934665603ull;
  const auto mix = [&h](const void* data, std::size_t bytes) {
    const auto* p = static_cast<const unsigned char*>(data);
    std::size_t i = 0;
    for (; i + 8 <= bytes; i += 8) {
      std::uint64_t v;
      std::memcpy(&v, p + i, 8);
      h = (h ^ v) * 1099511628211ull;
    }
    for (; i < bytes; ++i)
      h = (h ^ p[i]) * 1099511628211ull;
  };
  mix(pixelSigma.pixels.data(), pixelSigma.pixels.size() * sizeof(float));
  mix(unmeasured.data(), unmeasured.size());
  return h;
}

stats::NoiseModel CudaPreprocess::estimateNoiseModel(const FrameCube& zeroBiased, const Image& pixelSigma,
                                                     const std::vector<std::uint8_t>& unmeasured,
                                                     const stats::NoiseModelParams& params,
                                                     CancelToken& cancel) {
  if (stagewise()) {
    finishHostCopies();
    m_note.clear();
    return stats::estimateNoiseModel(zeroBiased, pixelSigma, unmeasured, params, cancel);
  }
  return finishingCopiesOnError(
      [&] { return noiseModel(zeroBiased, pixelSigma, unmeasured, params, cancel); });
}

stats::NoiseModel CudaPreprocess::noiseModel(const FrameCube& zeroBiased, const Image& pixelSigma,
                                             const std::vector<std::uint8_t>& unmeasured,
                                             const stats::NoiseModelParams& params, CancelToken& cancel) {
  Stopwatch sw;
  const int w = zeroBiased.width(), h = zeroBiased.height();
  const std::size_t nf = zeroBiased.frameCount(), np = zeroBiased.framePixels();
  // The variance map and the reference sigma before the frame scales: the CPU's own function on a cube of
  // no frames (its frame-scale loop is then empty and the typical scale 1), made beside zeroBias when it was
  // given these inputs.
  std::optional<NoiseShape> made = std::exchange(m_noiseShape, std::nullopt);
  const bool madeBeside =
      made && made->sigma == pixelSigma.pixels.data() && made->sigmaSize == pixelSigma.pixels.size() &&
      made->unmeasured == unmeasured.data() && made->unmeasuredSize == unmeasured.size() &&
      made->params.smoothBoxPx == params.smoothBoxPx &&
      made->params.noisyPixelRatio == params.noisyPixelRatio &&
      made->params.sampleStride == params.sampleStride &&
      made->hash == noiseShapeHash(pixelSigma, unmeasured);
  stats::NoiseModel m =
      madeBeside ? std::move(made->model)
                 : stats::estimateNoiseModel(FrameCube(w, h, 0), pixelSigma, unmeasured, params, cancel);
  const double hostMap = sw.lap();
  ST_CUDA_CHECK(cudaSetDevice(m_device.ordinal));
  DeviceResources& r = resources();
  cudaStream_t s = r.compute.get();
  // The frames zeroBias or removeResidualMeans left on the device, when this is that cube unchanged (its
  // host copy may still be downloading).
  const bool kept = keptIs(zeroBiased);
  DeviceBuffer<float> uploaded;
  const float* pix = m_kept.get();
  if (!kept) {
    finishHostCopies();  // the host frames are read
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
  m_note = "noise model on " + name() + ": variance map " +
           (madeBeside ? "made on the host beside the zero-bias stages (checked in " + ms(hostMap) + ")"
                       : "on the host " + ms(hostMap)) +
           ", " + (kept ? "frames already on the device" : "upload " + ms(upload)) + ", frame medians " +
           ms(kernels);
  return m;
}

}  // namespace st::gpu

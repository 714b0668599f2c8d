// The sky rate's chain's phase correlations on the device (issue 16; phase_correlation_kernels.cu): the
// links' images written as windowed floats straight into the pinned staging buffers on every core, a
// staging buffer's pairs uploaded and correlated while the host fills the other, the peaks downloaded once.
#include <algorithm>
#include <vector>

#include "cuda_preprocess.hpp"
#include "phase_correlation_kernels.hpp"
#include "st/common/parallel.hpp"

namespace st::gpu {

using namespace preprocess_detail;

namespace {

PhaseFftAxis axisOf(int n, const std::vector<int>& radices, const DeviceBuffer<float2>& twiddles) {
  PhaseFftAxis a;
  a.n = n;
  a.stages = static_cast<int>(radices.size());
  std::copy(radices.begin(), radices.end(), a.radix);
  a.twiddle = twiddles.get();
  return a;
}

}  // namespace

std::optional<std::vector<detect::PhasePeak>> CudaPreprocess::phaseCorrelations(
    const detect::PhaseCorrelationBatch& batch) {
  if (phaseCorrelationsOnHost() || stagewise()) return std::nullopt;
  if (batch.pairs == 0 || !batch.fill || batch.width <= 0 || batch.height <= 0 || batch.nx < batch.width ||
      batch.ny < batch.height)
    return std::nullopt;
  const std::vector<int> rx = phaseFftRadices(batch.nx), ry = phaseFftRadices(batch.ny);
  constexpr std::size_t kMaxStages = sizeof(PhaseFftAxis::radix) / sizeof(int);
  if (rx.empty() || ry.empty() || rx.size() > kMaxStages || ry.size() > kMaxStages) return std::nullopt;
  const std::size_t plane = static_cast<std::size_t>(batch.width) * batch.height;
  const std::size_t pairFloats = 2 * plane;
  // A staging buffer's worth of pairs at a time; pairs larger than one (images over 2048^2) stay on the CPU.
  const std::size_t perStaging = kStagingBytes / (pairFloats * sizeof(float));
  if (perStaging == 0) return std::nullopt;
  const std::size_t chunk = std::min(perStaging, batch.pairs);
  const std::size_t transform = static_cast<std::size_t>(batch.nx) * batch.ny;

  Stopwatch sw;
  ST_CUDA_CHECK(cudaSetDevice(m_device.ordinal));
  DeviceResources& r = resources();
  cudaStream_t s = r.compute.get();
  const DeviceBuffer<float2> twx = toDevice(phaseFftTwiddles(batch.nx));
  const DeviceBuffer<float2> twy = batch.ny == batch.nx ? DeviceBuffer<float2>() : toDevice(phaseFftTwiddles(batch.ny));
  DeviceBuffer<float> images(chunk * pairFloats), surface(chunk * transform), rowMax(chunk * batch.ny);
  DeviceBuffer<float2> spectra(chunk * 2 * transform);
  DeviceBuffer<int> rowArg(chunk * batch.ny);
  DeviceBuffer<double> peaks(4 * batch.pairs);
  PhaseCorrelationLaunch p{};
  p.images = images.get();
  p.width = batch.width;
  p.height = batch.height;
  p.x = axisOf(batch.nx, rx, twx);
  p.y = axisOf(batch.ny, ry, batch.ny == batch.nx ? twx : twy);
  p.spectra = spectra.get();
  p.surface = surface.get();
  p.rowMax = rowMax.get();
  p.rowArg = rowArg.get();
  for (std::size_t p0 = 0; p0 < batch.pairs; p0 += chunk) {
    const std::size_t n = std::min(chunk, batch.pairs - p0);
    const int b = r.nextStaging;
    r.nextStaging ^= 1;
    r.stagingFree[b].sync();
    float* staging = static_cast<float*>(r.staging(b));
    parallelFor(n, 1, [&](std::size_t q0, std::size_t q1) {
      for (std::size_t q = q0; q < q1; ++q)
        batch.fill(p0 + q, staging + q * pairFloats, staging + q * pairFloats + plane);
    });
    ST_CUDA_CHECK(
        cudaMemcpyAsync(images.get(), staging, n * pairFloats * sizeof(float), cudaMemcpyHostToDevice, s));
    r.stagingFree[b].record(s);
    p.pairs = static_cast<int>(n);
    p.peaks = peaks.get() + 4 * p0;
    launchPhaseCorrelation(p, s);
  }
  std::vector<double> host(4 * batch.pairs);
  ST_CUDA_CHECK(cudaMemcpyAsync(host.data(), peaks.get(), host.size() * sizeof(double), cudaMemcpyDeviceToHost, s));
  r.compute.sync();
  std::vector<detect::PhasePeak> out(batch.pairs);
  for (std::size_t k = 0; k < batch.pairs; ++k)
    out[k] = {host[4 * k], host[4 * k + 1], host[4 * k + 2], host[4 * k + 3] != 0.0};
  m_note = "sky rate phase correlations: " + std::to_string(batch.pairs) + " pairs of " +
           std::to_string(batch.width) + " x " + std::to_string(batch.height) + " in " + ms(sw.lap());
  return out;
}

}  // namespace st::gpu

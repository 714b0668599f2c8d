// The sky rate's chain's phase correlations on the device (issue 16; phase_correlation_kernels.cu): the
// links' images written as windowed floats straight into the pinned staging buffers on every core, a
// staging buffer's pairs uploaded and correlated while the host fills the other (a batch of more pairs than
// one holds: 16 of 512^2, 2 of 1432 x 1370), the peaks downloaded once.
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
  if (!m_phase || m_phase->width != batch.width || m_phase->height != batch.height || m_phase->nx != batch.nx ||
      m_phase->ny != batch.ny || m_phase->pairs < chunk) {
    // Sized for this batch's chunk: the chain's groups of links all ask for the same number.
    m_phase.reset();  // the old buffers freed before the new ones are made
    auto w = std::make_unique<PhaseWorkspace>();
    w->width = batch.width;
    w->height = batch.height;
    w->nx = batch.nx;
    w->ny = batch.ny;
    w->pairs = chunk;
    w->twiddleX = toDevice(phaseFftTwiddles(batch.nx));
    if (batch.ny != batch.nx) w->twiddleY = toDevice(phaseFftTwiddles(batch.ny));
    w->images = DeviceBuffer<float>(chunk * pairFloats);
    w->surface = DeviceBuffer<float>(chunk * transform);
    w->rowMax = DeviceBuffer<float>(chunk * batch.ny);
    w->spectra = DeviceBuffer<float2>(chunk * 2 * transform);
    w->rowArg = DeviceBuffer<int>(chunk * batch.ny);
    m_phase = std::move(w);
  }
  PhaseWorkspace& w = *m_phase;
  if (w.peaks.size() < 4 * batch.pairs) w.peaks = DeviceBuffer<double>(4 * batch.pairs);
  PhaseCorrelationLaunch p{};
  p.images = w.images.get();
  p.width = batch.width;
  p.height = batch.height;
  p.x = axisOf(batch.nx, rx, w.twiddleX);
  p.y = axisOf(batch.ny, ry, batch.ny == batch.nx ? w.twiddleX : w.twiddleY);
  p.spectra = w.spectra.get();
  p.surface = w.surface.get();
  p.rowMax = w.rowMax.get();
  p.rowArg = w.rowArg.get();
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
        cudaMemcpyAsync(w.images.get(), staging, n * pairFloats * sizeof(float), cudaMemcpyHostToDevice, s));
    r.stagingFree[b].record(s);
    p.pairs = static_cast<int>(n);
    p.peaks = w.peaks.get() + 4 * p0;
    launchPhaseCorrelation(p, s);
  }
  std::vector<double> host(4 * batch.pairs);
  ST_CUDA_CHECK(cudaMemcpyAsync(host.data(), w.peaks.get(), host.size() * sizeof(double), cudaMemcpyDeviceToHost, s));
  r.compute.sync();
  std::vector<detect::PhasePeak> out(batch.pairs);
  for (std::size_t k = 0; k < batch.pairs; ++k)
    out[k] = {host[4 * k], host[4 * k + 1], host[4 * k + 2], host[4 * k + 3] != 0.0};
  m_note = "sky rate phase correlations: " + std::to_string(batch.pairs) + " pairs of " +
           std::to_string(batch.width) + " x " + std::to_string(batch.height) + " in " + ms(sw.lap());
  return out;
}

}  // namespace st::gpu

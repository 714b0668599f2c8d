// CudaPreprocess::registrationLinks: registration's sampled links (detect::RegistrationLinkBatch) from the
// frames the frame backgrounds kept on the device, so that the host frames (whose download may still run
// behind, issue 16) are not read.
#include <algorithm>
#include <map>
#include <span>
#include <type_traits>

#include "cuda_preprocess.hpp"
#include "registration_link_kernels.hpp"
#include "sky_stack_kernels.hpp"
#include "st/common/sparse_bytes.hpp"

namespace st::gpu {

using namespace preprocess_detail;

namespace {

/// Benchmark knob: ST_GPU_REGISTRATION_ON_HOST=1 leaves registration's sampled links to the CPU, as before
/// 2026-12-03, for before/after figures from one binary.
bool registrationOnHost() {
  return envKnob("ST_GPU_REGISTRATION_ON_HOST");
}

}  // namespace

std::optional<std::vector<detect::RegistrationLinkPeak>> CudaPreprocess::registrationLinks(
    const FrameCube& cube, const detect::RegistrationLinkBatch& batch) {
  const std::size_t nf = cube.frameCount(), np = cube.framePixels();
  const bool frames = m_sepFramesValid && m_sepFramesData == cube.pixels().data() &&
                      m_sepFrames.size() == cube.pixels().size() && m_sepFrames.size() > 0;
  const int bw = batch.width, bh = batch.height, bin = batch.bin;
  const std::vector<int> rx = phaseFftRadices(bw), ry = phaseFftRadices(bh);
  if (registrationOnHost() || !frames || batch.pairs.empty() || bin < 1 || rx.empty() || ry.empty() ||
      bw * bin > cube.width() || bh * bin > cube.height() || !batch.taperX || !batch.taperY ||
      !batch.highPass || batch.taperX->size() != static_cast<std::size_t>(bw) ||
      batch.taperY->size() != static_cast<std::size_t>(bh) ||
      batch.highPass->size() != static_cast<std::size_t>(bw / 2 + 1) * bh)
    return std::nullopt;
  Stopwatch sw;
  // Each frame once (a slot), the pairs by slot.
  std::map<std::size_t, int> slotOf;
  std::vector<int> slotFrame, pairSlots;
  for (const auto& [later, earlier] : batch.pairs) {
    for (const std::size_t n : {later, earlier}) {
      if (n >= nf) return std::nullopt;
      const auto [it, added] = slotOf.emplace(n, static_cast<int>(slotFrame.size()));
      if (added) slotFrame.push_back(static_cast<int>(n));
      pairSlots.push_back(it->second);
    }
  }
  const std::size_t slots = slotFrame.size(), pairs = batch.pairs.size();
  const std::size_t pixels = static_cast<std::size_t>(bw) * bh;
  // Its buffers stay until zeroBias, beside the kept cube: at most 3 GiB of them (64 links of 2048^2
  // binned frames would take ~11 GB), else the CPU measures the links.
  const std::size_t bytes = slots * (np + (np + 6) / 7 * 4 + pixels * 12) + pairs * pixels * 12;
  if (bytes > (std::size_t{3} << 30)) return std::nullopt;
  ST_CUDA_CHECK(cudaSetDevice(m_device.ordinal));
  DeviceResources& r = resources();
  cudaStream_t s = r.compute.get();
  // The slots' masks (the host's: the hot pixels were masked after the frame backgrounds): copied on the
  // device from the kept mask when it is the host's (maskedInAllFrames applied the hot pixels to it); else
  // their few set bytes scattered into zeroed buffers (11 ms of host scans for 1500 x 512^2, H200
  // 2026-12-03).
  DeviceBuffer<std::uint8_t> masks;
  bool masksOnDevice = false;
  if (cube.mask().size() == cube.pixels().size() && m_sepMaskVouched &&
      m_sepMask.size() == cube.mask().size()) {
    masks = DeviceBuffer<std::uint8_t>(slots * np);
    for (std::size_t k = 0; k < slots; ++k)
      ST_CUDA_CHECK(cudaMemcpyAsync(masks.get() + k * np,
                                    m_sepMask.get() + static_cast<std::size_t>(slotFrame[k]) * np, np,
                                    cudaMemcpyDeviceToDevice, s));
    masksOnDevice = true;
  } else if (cube.mask().size() == cube.pixels().size()) {
    masks = DeviceBuffer<std::uint8_t>(slots * np);
    ST_CUDA_CHECK(cudaMemsetAsync(masks.get(), 0, slots * np, s));
    std::vector<std::uint64_t> index;
    std::vector<std::uint8_t> value;
    for (std::size_t k = 0; k < slots; ++k) {
      const std::span<const std::uint8_t> m(cube.mask().data() + static_cast<std::size_t>(slotFrame[k]) * np,
                                            np);
      const std::optional<SparseBytes> sparse = sparseBytes(m, np / 64);
      if (!sparse) {  // a frame's mask over 1/64 set: copied whole
        ST_CUDA_CHECK(cudaMemcpyAsync(masks.get() + k * np, m.data(), np, cudaMemcpyHostToDevice, s));
        continue;
      }
      for (std::size_t e = 0; e < sparse->index.size(); ++e) {
        index.push_back(k * np + sparse->index[e]);
        value.push_back(sparse->value[e]);
      }
    }
    if (!index.empty()) {
      const DeviceBuffer<std::uint64_t> indexD = toDevice(index);
      const DeviceBuffer<std::uint8_t> valueD = toDevice(value);
      launchScatter(masks.get(), indexD.get(), valueD.get(), index.size(), s);
      ST_CUDA_CHECK(cudaStreamSynchronize(s));  // before the entries are freed
    }
    ST_CUDA_CHECK(cudaStreamSynchronize(s));  // the whole frames' masks copied (pageable: before returning)
  }
  const double maskSeconds = sw.lap();
  const DeviceBuffer<int> slotFrameD = toDevice(slotFrame), pairSlotsD = toDevice(pairSlots);
  const DeviceBuffer<float> taperX = toDevice(*batch.taperX), taperY = toDevice(*batch.taperY),
                            highPass = toDevice(*batch.highPass);
  const DeviceBuffer<float2> twX = toDevice(phaseFftTwiddles(bw)), twY = toDevice(phaseFftTwiddles(bh));
  const std::size_t sampleStride = (np + 6) / 7;
  // The work buffers (~0.6 GB for 64 links of 512^2 frames) are kept until zeroBias: freeing them here would
  // wait for the frame backgrounds' download running behind.
  if (!m_registration) m_registration = std::make_unique<RegistrationWorkspace>();
  RegistrationWorkspace& ws = *m_registration;
  const auto fit = [](auto& buffer, std::size_t count) {
    if (buffer.size() < count) buffer = std::remove_reference_t<decltype(buffer)>(count);
    return buffer.get();
  };
  float* samples = fit(ws.samples, slots * sampleStride);
  float* median = fit(ws.median, slots);
  float* sigma = fit(ws.sigma, slots);
  float* images = fit(ws.images, slots * pixels);
  float2* spectra = fit(ws.spectra, slots * pixels);
  float2* products = fit(ws.products, pairs * pixels);
  float* surface = fit(ws.surface, pairs * pixels);
  float* rowMax = fit(ws.rowMax, pairs * bh);
  int* rowArg = fit(ws.rowArg, pairs * bh);
  double* rowSum = fit(ws.rowSum, pairs * bh);
  double* rowSum2 = fit(ws.rowSum2, pairs * bh);
  double* peaks = fit(ws.peaks, pairs * 3);
  RegistrationLinkLaunch p;
  p.frames = m_sepFrames.get();
  p.masks = masks.size() ? masks.get() : nullptr;
  p.slotFrame = slotFrameD.get();
  p.slots = static_cast<int>(slots);
  p.width = cube.width();
  p.height = cube.height();
  p.bin = bin;
  p.bw = bw;
  p.bh = bh;
  p.samples = samples;
  p.sampleStride = sampleStride;
  p.median = median;
  p.sigma = sigma;
  p.taperX = taperX.get();
  p.taperY = taperY.get();
  p.images = images;
  const auto axis = [](int n, const std::vector<int>& radices, const float2* twiddles) {
    PhaseFftAxis a;
    a.n = n;
    a.stages = static_cast<int>(radices.size());
    std::copy(radices.begin(), radices.end(), a.radix);
    a.twiddle = twiddles;
    return a;
  };
  p.x = axis(bw, rx, twX.get());
  p.y = axis(bh, ry, twY.get());
  p.spectra = spectra;
  p.highPass = highPass.get();
  p.pairSlots = pairSlotsD.get();
  p.pairs = static_cast<int>(pairs);
  p.products = products;
  p.surface = surface;
  p.rowMax = rowMax;
  p.rowArg = rowArg;
  p.rowSum = rowSum;
  p.rowSum2 = rowSum2;
  p.peaks = peaks;
  const double buffers = sw.lap();
  launchRegistrationLinks(p, s);
  std::vector<double> peaksH(pairs * 3);
  ST_CUDA_CHECK(
      cudaMemcpyAsync(peaksH.data(), peaks, peaksH.size() * sizeof(double), cudaMemcpyDeviceToHost, s));
  ST_CUDA_CHECK(cudaStreamSynchronize(s));
  std::vector<detect::RegistrationLinkPeak> out(pairs);
  for (std::size_t k = 0; k < pairs; ++k)
    out[k] = {peaksH[3 * k], peaksH[3 * k + 1], peaksH[3 * k + 2], true};
  const double kernels = sw.lap();
  m_note = "registration's " + std::to_string(pairs) + " sampled links on " + name() + " from the frame " +
           "backgrounds' frames: masks " + (masksOnDevice ? "from the kept mask " : "from the host's ") +
           ms(maskSeconds) + ", buffers " + ms(buffers) + ", kernels " + ms(kernels);
  return out;
}

}  // namespace st::gpu

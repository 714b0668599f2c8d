// CudaPreprocess: what the stages before the per-pixel background make from the calibrated cube prefetch()
// uploads behind them (issue 16), with no upload of their own: the sky rate's block sums
// (detect::shiftedSums), the cosmic-ray fills patched into the device's copy, and the stacks at the sky rate
// (detect::stackAtSkyRate) that the static-source search and the PSF stage ask for. The sums are the CPU's
// (sky_stack_kernels.cu), so the results are equal.
#include <algorithm>
#include <optional>
#include <vector>

#include "cuda_preprocess.hpp"
#include "resident_cube.hpp"
#include "sky_stack_kernels.hpp"
#include "st/common/parallel.hpp"
#include "st/detect/moving_mask.hpp"

namespace st::gpu {

using namespace preprocess_detail;

std::shared_ptr<CudaPreprocess::Prefetch> CudaPreprocess::readyPrefetch(const FrameCube& cube,
                                                                        bool waitForUpload) {
  if (stagewise()) return nullptr;
  std::shared_ptr<Prefetch> pf = m_prefetch;
  if (!pf || pf->data != cube.pixels().data() || pf->size != cube.pixels().size() ||
      pf->maskSize != cube.mask().size())
    return nullptr;
  // Without waiting: the CPU's stack (~0.1 s for 1500 x 512^2 on 16 threads) is quicker than waiting for an
  // upload that has just begun. Frames kept from the frame backgrounds leave only the mask's upload (a few ms
  // when sparse): that is waited for (the sky rate's block pairs come right after the prefetch starts).
  if (!waitForUpload && !pf->finished.load() && !pf->keptFrames) return nullptr;
  pf->join();
  if (!pf->ok || pf->key != (pf->shapeKeyOnly ? cubeShapeKey(cube) : cubeKey(cube))) return nullptr;
  return pf;
}

void CudaPreprocess::patchPrefetch(const FrameCube& cube, const std::vector<std::uint64_t>& pixels) {
  std::shared_ptr<Prefetch> pf = m_prefetch;
  if (!pf || pf->data != cube.pixels().data() || pf->size != cube.pixels().size()) return;
  try {
    pf->join();
    if (!pf->ok) return;
    if (!pixels.empty()) {
      std::vector<float> values(pixels.size());
      for (std::size_t k = 0; k < pixels.size(); ++k)
        values[k] = cube.pixels()[pixels[k]];
      ST_CUDA_CHECK(cudaSetDevice(m_device.ordinal));
      DeviceResources& r = resources();
      DeviceBuffer<std::uint64_t> idx = toDevice(pixels);
      DeviceBuffer<float> val = toDevice(values);
      launchScatter(pf->pix.get(), idx.get(), val.get(), pixels.size(), r.compute.get());
      r.compute.sync();
    }
    pf->shapeKeyOnly = framesPending(cube);  // the pipeline waits for the frames before the cosmic rays
    pf->key = pf->shapeKeyOnly ? cubeShapeKey(cube) : cubeKey(cube);
  } catch (const std::exception&) {
    // Dropped: the stages after upload the cube themselves.
    pf->ok = false;
    pf->pix = DeviceBuffer<float>();
    pf->mask = DeviceBuffer<std::uint8_t>();
  }
}

std::optional<std::vector<detect::ShiftedSums>> CudaPreprocess::shiftedSums(
    const FrameCube& cube, const std::vector<detect::ShiftedBlock>& blocks, double background,
    detect::ShiftedSumsForm form) {
  if (form == detect::ShiftedSumsForm::DoubleMeans && blockPairsOnHost()) return std::nullopt;
  const trace::Scope whole("block sums on the device (with freeing)");
  std::optional<trace::Scope> part(std::in_place, "block sums: prefetch ready");
  const std::shared_ptr<Prefetch> pf = readyPrefetch(cube, false);
  if (!pf || blocks.empty()) return std::nullopt;
  const std::size_t nf = cube.frameCount(), np = cube.framePixels(), k = blocks.size();
  std::vector<int> first(k), start(k + 1, 0), sx, sy;
  for (std::size_t b = 0; b < k; ++b) {
    const detect::ShiftedBlock& blk = blocks[b];
    if (blk.last > nf || blk.first > blk.last || blk.sx.size() != blk.last - blk.first ||
        blk.sy.size() != blk.sx.size())
      return std::nullopt;
    first[b] = static_cast<int>(blk.first);
    sx.insert(sx.end(), blk.sx.begin(), blk.sx.end());
    sy.insert(sy.end(), blk.sy.begin(), blk.sy.end());
    start[b + 1] = static_cast<int>(sx.size());
  }
  Stopwatch sw;
  part.emplace("block sums: device buffers and launch");
  ST_CUDA_CHECK(cudaSetDevice(m_device.ordinal));
  DeviceResources& r = resources();
  cudaStream_t s = r.compute.get();
  DeviceBuffer<int> firstD = toDevice(first), startD = toDevice(start);
  DeviceBuffer<int> sxD = toDevice(sx.empty() ? std::vector<int>{0} : sx);
  DeviceBuffer<int> syD = toDevice(sy.empty() ? std::vector<int>{0} : sy);
  // The blocks' means and counts as floats (detect::ShiftedSums::mean, frames): 8 bytes a pixel a block to
  // download instead of the sums' 16 (84 MB for 20 blocks of 512^2, twice a pre-processing); the block
  // pairs' means in double (8 bytes).
  const bool doubles = form == detect::ShiftedSumsForm::DoubleMeans;
  DeviceBuffer<float> mean(doubles ? 0 : k * np), frames(doubles ? 0 : k * np);
  DeviceBuffer<double> doubleMean(doubles ? k * np : 0);
  ShiftedSumsLaunch p{};
  p.pix = pf->pix.get();
  p.mask = pf->maskSize ? pf->mask.get() : nullptr;
  p.width = cube.width();
  p.height = cube.height();
  p.blocks = static_cast<int>(k);
  p.first = firstD.get();
  p.start = startD.get();
  p.sx = sxD.get();
  p.sy = syD.get();
  p.background = background;
  p.mean = doubles ? nullptr : mean.get();
  p.frames = doubles ? nullptr : frames.get();
  p.doubleMean = doubles ? doubleMean.get() : nullptr;
  launchShiftedSums(p, s);
  part.emplace("block sums: host images");
  // The host's images allocated and zeroed on every core while the kernel runs, not on this thread.
  std::vector<detect::ShiftedSums> out(k);
  parallelFor(k, 1, [&](std::size_t b0, std::size_t b1) {
    for (std::size_t b = b0; b < b1; ++b) {
      if (doubles) {
        out[b].doubleMean.resize(np);
      } else {
        out[b].mean.resize(np);
        out[b].frames.resize(np);
      }
    }
  });
  // Through the pinned staging buffers, copied out on every core (pageable copies ran at a few GB/s on one
  // thread), gathered.
  part.reset();
  std::vector<DownloadPiece> pieces;
  for (std::size_t b = 0; b < k; ++b) {
    if (doubles) {
      pieces.push_back({out[b].doubleMean.data(), doubleMean.get() + b * np, np * sizeof(double)});
      continue;
    }
    pieces.push_back({out[b].mean.data(), mean.get() + b * np, np * sizeof(float)});
    pieces.push_back({out[b].frames.data(), frames.get() + b * np, np * sizeof(float)});
  }
  downloadPieces(r, pieces, s);
  m_note = "the sky rate's " + std::to_string(k) + (doubles ? " block means on " : " block sums on ") +
           name() + ": " + ms(sw.lap());
  return out;
}

std::optional<detect::SkyStack> CudaPreprocess::skyStack(const FrameCube& cube, Velocity rate,
                                                         double subtract, std::size_t first,
                                                         std::size_t last) {
  const std::size_t nf = cube.frameCount();
  if (last == 0 || last > nf) last = nf;
  Stopwatch sw;
  const trace::Scope whole("stack on the device (with freeing)");
  std::optional<trace::Scope> part(std::in_place, "stack: prefetch ready");
  const std::shared_ptr<Prefetch> pf = readyPrefetch(cube, false);
  if (!pf || first >= last) return std::nullopt;
  const double waited = sw.lap();
  part.emplace("stack: device buffers and launch");
  ST_CUDA_CHECK(cudaSetDevice(m_device.ordinal));
  DeviceResources& r = resources();
  cudaStream_t s = r.compute.get();
  const MovingMask geom(cube, rate);
  std::vector<int> sx(nf), sy(nf);
  for (std::size_t n = 0; n < nf; ++n) {
    sx[n] = geom.shiftX(n);
    sy[n] = geom.shiftY(n);
  }
  detect::SkyStack out;
  out.x0 = geom.x0();
  out.y0 = geom.y0();
  const int cw = geom.canvasWidth(), ch = geom.canvasHeight();
  const std::size_t nc = static_cast<std::size_t>(cw) * ch;
  DeviceBuffer<int> sxD = toDevice(sx), syD = toDevice(sy);
  DeviceBuffer<float> mean(std::max<std::size_t>(1, nc)), count(std::max<std::size_t>(1, nc)),
      mx(std::max<std::size_t>(1, nc));
  SkyStackLaunch p{};
  p.pix = pf->pix.get();
  p.mask = pf->maskSize ? pf->mask.get() : nullptr;
  p.width = cube.width();
  p.height = cube.height();
  p.shiftX = sxD.get();
  p.shiftY = syD.get();
  p.first = static_cast<int>(first);
  p.last = static_cast<int>(last);
  p.x0 = out.x0;
  p.y0 = out.y0;
  p.cw = cw;
  p.ch = ch;
  p.subtract = subtract;
  p.mean = mean.get();
  p.count = count.get();
  p.max = mx.get();
  launchSkyStack(p, s);
  part.emplace("stack: host images");
  out.mean = Image(cw, ch);
  out.count = Image(cw, ch);
  out.max = Image(cw, ch);
  part.reset();
  if (nc > 0)  // through the pinned staging buffers
    downloadPieces(r,
                   {{out.mean.data(), mean.get(), nc * 4},
                    {out.count.data(), count.get(), nc * 4},
                    {out.max.data(), mx.get(), nc * 4}},
                   s);
  r.compute.sync();
  m_note = "stack at the sky rate on " + name() + " (frames " + std::to_string(first) + " to " +
           std::to_string(last) + "): join " + ms(waited) + ", " + ms(sw.lap());
  return out;
}

std::optional<calib::CosmicRayPreTestWords> CudaPreprocess::cosmicRayPreTest(const FrameCube& cube,
                                                                             float thr) {
  const std::size_t nf = cube.frameCount(), np = cube.framePixels();
  if (nf < 3 || np == 0 || nf * np >= (std::size_t{1} << 37)) return std::nullopt;
  Stopwatch sw;
  const std::shared_ptr<Prefetch> pf = readyPrefetch(cube, false);
  if (!pf) return std::nullopt;
  ST_CUDA_CHECK(cudaSetDevice(m_device.ordinal));
  DeviceResources& r = resources();
  cudaStream_t s = r.compute.get();
  // Room for a non-zero word in 16 (noise passes at ~1e-4 a pixel: a word in ~300); more and the CPU makes
  // it (a cube of bright, moving structure).
  const std::size_t words = (nf * np + 31) / 32;
  const std::size_t capacity = std::max<std::size_t>(1024, words / 16);
  DeviceBuffer<unsigned long long> found(capacity), count(1);
  ST_CUDA_CHECK(cudaMemsetAsync(count.get(), 0, sizeof(unsigned long long), s));
  launchCosmicRayPreTest(pf->pix.get(), nf, np, thr, found.get(), capacity, count.get(), s);
  unsigned long long n = 0;
  ST_CUDA_CHECK(cudaMemcpyAsync(&n, count.get(), sizeof n, cudaMemcpyDeviceToHost, s));
  r.compute.sync();
  if (n > capacity) return std::nullopt;
  std::vector<unsigned long long> packed(n);
  if (n > 0) {
    ST_CUDA_CHECK(cudaMemcpyAsync(packed.data(), found.get(), n * sizeof(unsigned long long),
                                  cudaMemcpyDeviceToHost, s));
    r.compute.sync();
  }
  const double kernel = sw.lap();
  std::sort(packed.begin(), packed.end());  // by word index (the high half), as the CPU lists them
  calib::CosmicRayPreTestWords out;
  out.index.resize(n);
  out.bits.resize(n);
  for (std::size_t j = 0; j < n; ++j) {
    out.index[j] = packed[j] >> 32;
    out.bits[j] = static_cast<std::uint32_t>(packed[j] & 0xffffffffull);
  }
  m_note = "cosmic-ray pre-test on " + name() + ": " + std::to_string(n) +
           " non-zero words, kernel and read-back " + ms(kernel) + ", sorted " + ms(sw.lap());
  return out;
}

std::optional<std::vector<float>> CudaPreprocess::filteredSnr(const detect::FilteredSnrInputs& in) {
  const std::size_t np = static_cast<std::size_t>(std::max(0, in.width)) * std::max(0, in.height);
  if (np == 0 || in.r < 0 || !in.rc || !in.count || !in.k) return std::nullopt;
  Stopwatch sw;
  ST_CUDA_CHECK(cudaSetDevice(m_device.ordinal));
  DeviceResources& r = resources();
  cudaStream_t s = r.compute.get();
  const std::size_t taps = static_cast<std::size_t>(2 * in.r + 1) * (2 * in.r + 1);
  DeviceBuffer<float> rc(np), count(np), out(np);
  DeviceBuffer<double> k(taps);
  // Both ways through the pinned staging buffers, copied on every core (8 calls a pre-processing: pageable
  // copies of their 12 MB each took a few ms on one thread).
  stagedUpload(r, rc.get(), in.rc, np * sizeof(float), s, true);
  stagedUpload(r, count.get(), in.count, np * sizeof(float), s, true);
  ST_CUDA_CHECK(cudaMemcpyAsync(k.get(), in.k, taps * sizeof(double), cudaMemcpyHostToDevice, s));
  launchFilteredSnr(rc.get(), count.get(), k.get(), in.width, in.height, in.r, in.sigma, out.get(), s);
  std::vector<float> host(np);
  download(r, host.data(), out.get(), np * sizeof(float), s);
  m_note = "filtered SNR on " + name() + ": " + ms(sw.lap());
  return host;
}

}  // namespace st::gpu

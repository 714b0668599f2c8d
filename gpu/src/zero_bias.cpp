// zero_bias.hpp: the host side of star subtraction and zeroing on a cube kept on the device. The tables
// (blocks of frames, region positions, the fractional offsets, the residuals' verdicts, the masks' positions)
// come from core's own functions (detect::planStarTemplate, starTemplateFractionalOffset,
// starResidualVerdict, maskedPositions, coveredInSomeFrame); the kernels do the per-pixel work.
#include "zero_bias.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cmath>
#include <optional>
#include <string>
#include <utility>

#include "cuda_check.hpp"
#include "st/common/error.hpp"
#include "zero_bias_kernels.hpp"

namespace st::gpu {
namespace {

template <class T>
std::vector<T> toHost(const DeviceBuffer<T>& d, std::size_t count, cudaStream_t s) {
  std::vector<T> out(count);
  if (count) {
    ST_CUDA_CHECK(cudaMemcpyAsync(out.data(), d.get(), count * sizeof(T), cudaMemcpyDeviceToHost, s));
    ST_CUDA_CHECK(cudaStreamSynchronize(s));
  }
  return out;
}

DeviceBuffer<unsigned long long> zeros(std::size_t n, cudaStream_t s) {
  DeviceBuffer<unsigned long long> d(std::max<std::size_t>(n, 1));
  ST_CUDA_CHECK(cudaMemsetAsync(d.get(), 0, d.size() * sizeof(unsigned long long), s));
  return d;
}

/// The per-frame Lanczos tables on the device (sign +1: sampling the frames at +f; -1: the template at -f).
struct LanczosTables {
  DeviceBuffer<int> sx, sy, ox, oy;
  DeviceBuffer<double> wx, wy;
  LanczosFrames view() const { return {sx.get(), sy.get(), ox.get(), oy.get(), wx.get(), wy.get()}; }
};

LanczosTables lanczosTables(const MovingMask& region, const FrameCube& cube, const std::vector<double>& dt,
                            double sign) {
  const std::size_t nf = cube.frameCount();
  std::vector<int> sx(nf), sy(nf), ox(nf), oy(nf);
  std::vector<double> wx(6 * nf), wy(6 * nf);
  for (std::size_t n = 0; n < nf; ++n) {
    const auto [fx, fy] = detect::starTemplateFractionalOffset(region, cube, n, dt[n]);
    ox[n] = detect::lanczos3Weights(sign > 0 ? fx : -fx, wx.data() + 6 * n);
    oy[n] = detect::lanczos3Weights(sign > 0 ? fy : -fy, wy.data() + 6 * n);
    sx[n] = region.shiftX(n);
    sy[n] = region.shiftY(n);
  }
  return {toDevice(sx), toDevice(sy), toDevice(ox), toDevice(oy), toDevice(wx), toDevice(wy)};
}

void shiftsOf(const MovingMask& m, std::size_t nf, std::vector<int>& sx, std::vector<int>& sy) {
  sx.resize(nf);
  sy.resize(nf);
  for (std::size_t n = 0; n < nf; ++n) {
    sx[n] = m.shiftX(n);
    sy[n] = m.shiftY(n);
  }
}

}  // namespace

detect::StarSubtraction subtractStarTemplateOnDevice(const FrameCube& cube, DeviceCubeRef d,
                                                     const MovingMask& region, const float* sigma,
                                                     const detect::StarSubtractionParams& params,
                                                     cudaStream_t s, std::string* timing) {
  detect::StarSubtraction out;
  auto last = std::chrono::steady_clock::now();
  auto lap = [&](const char* phase) {
    const auto now = std::chrono::steady_clock::now();
    if (timing) {
      char text[64];
      std::snprintf(text, sizeof text, "%s%s %.1f ms", timing->empty() ? "" : ", ", phase,
                    std::chrono::duration<double>(now - last).count() * 1e3);
      *timing += text;
    }
    last = now;
  };
  const std::size_t nf = cube.frameCount();
  const std::optional<detect::StarTemplatePlan> plan = detect::planStarTemplate(cube, region, params);
  if (!plan) return out;
  const std::vector<int>& targets = plan->targets;
  const std::vector<int>& pix = plan->positions;
  const std::vector<double> dt = cube.timeOffsetsS();
  const int nb = plan->blocks;
  const std::vector<int>& blockOf = plan->blockOf;
  lap("regions and blocks");

  const int cw = region.canvasWidth(), ch = region.canvasHeight();
  const std::size_t np = pix.size();
  // The frames of each block in ascending order (the CPU's loop over n).
  std::vector<int> blockFrames, blockStart(nb + 1, 0);
  for (int b = 0; b < nb; ++b) {
    blockStart[b] = static_cast<int>(blockFrames.size());
    for (std::size_t n = 0; n < nf; ++n)
      if (blockOf[n] == b) blockFrames.push_back(static_cast<int>(n));
  }
  blockStart[nb] = static_cast<int>(blockFrames.size());

  // Per-block sums and counts of the resampled frames at the grown region's positions.
  const LanczosTables plus = lanczosTables(region, cube, dt, +1.0);
  DeviceBuffer<int> posD = toDevice(pix), framesD = toDevice(blockFrames), startD = toDevice(blockStart);
  DeviceBuffer<float> sumD(np * nb), cntD(np * nb);
  StarTemplateLaunch tl{};
  tl.pix = d.pix;
  tl.mask = d.mask;
  tl.width = d.width;
  tl.height = d.height;
  tl.positions = posD.get();
  tl.np = static_cast<int>(np);
  tl.cw = cw;
  tl.x0 = region.x0();
  tl.y0 = region.y0();
  tl.blockFrames = framesD.get();
  tl.blockStart = startD.get();
  tl.nb = nb;
  tl.lz = plus.view();
  tl.sum = sumD.get();
  tl.cnt = cntD.get();
  launchStarTemplateSums(tl, s);
  lap("block sums");

  // One template per block over the canvas (the CPU's loop, on the device: the frame counts summed are
  // whole numbers, so their total is the CPU's in any order).
  const std::size_t canvasSize = static_cast<std::size_t>(cw) * ch;
  DeviceBuffer<std::uint8_t> exclD = toDevice(plan->excluded);
  DeviceBuffer<float> tmplD(canvasSize * nb);
  DeviceBuffer<std::uint8_t> validD(canvasSize * nb);
  ST_CUDA_CHECK(cudaMemsetAsync(tmplD.get(), 0, canvasSize * nb * sizeof(float), s));
  ST_CUDA_CHECK(cudaMemsetAsync(validD.get(), 0, canvasSize * nb, s));
  DeviceBuffer<unsigned long long> frameTotals = zeros(2, s);
  launchStarTemplateBuild(sumD.get(), cntD.get(), static_cast<int>(np), nb, exclD.get(), posD.get(),
                          canvasSize, params.minTemplateFrames, tmplD.get(), validD.get(), frameTotals.get(),
                          frameTotals.get() + 1, s);
  const std::vector<unsigned long long> totals = toHost(frameTotals, 2, s);
  const double framesSum = static_cast<double>(totals[0]);
  const std::size_t framesN = static_cast<std::size_t>(totals[1]);
  out.meanTemplateFrames = framesN ? framesSum / framesN : 0.0;
  lap("templates");

  // Subtract, frame by frame, the block's template at -f; the residual variance per position.
  const LanczosTables minus = lanczosTables(region, cube, dt, -1.0);
  DeviceBuffer<int> targetsD = toDevice(targets), blockOfD = toDevice(blockOf);
  const std::size_t nt = targets.size();
  DeviceBuffer<double> r2D(nt), s2D(nt);
  DeviceBuffer<float> samplesD(nt);
  DeviceBuffer<unsigned long long> counts = zeros(2, s);
  StarSubtractLaunch sl{};
  sl.pix = d.pix;
  sl.width = d.width;
  sl.height = d.height;
  sl.nf = d.nf;
  sl.targets = targetsD.get();
  sl.nt = static_cast<int>(nt);
  sl.cw = cw;
  sl.ch = ch;
  sl.x0 = region.x0();
  sl.y0 = region.y0();
  sl.blockOf = blockOfD.get();
  sl.lz = minus.view();
  sl.tmpl = tmplD.get();
  sl.valid = validD.get();
  sl.sigma = sigma;
  sl.r2 = r2D.get();
  sl.s2 = s2D.get();
  sl.samples = samplesD.get();
  sl.counts = counts.get();
  lap("uploads");
  launchStarSubtract(sl, s);
  const std::vector<unsigned long long> c2 = toHost(counts, 2, s);
  out.pixelsSubtracted = c2[0];
  out.pixelsZeroed = c2[1];
  out.excess = MovingMask(cube, region.rate());
  if (sigma) {
    const std::vector<double> r2 = toHost(r2D, nt, s), s2 = toHost(s2D, nt, s);
    const std::vector<float> samples = toHost(samplesD, nt, s);
    std::vector<int> wPos;
    std::vector<float> wFactor;
    for (std::size_t k = 0; k < nt; ++k) {
      const double verdict = detect::starResidualVerdict(r2[k], s2[k], samples[k], params);
      if (verdict < 0.0) {
        out.excess.set(region.x0() + targets[k] % cw, region.y0() + targets[k] / cw);
      } else if (verdict > 0.0) {
        wPos.push_back(targets[k]);
        wFactor.push_back(static_cast<float>(verdict));
      }
    }
    out.whitenedPositions = wPos.size();
    out.excessPositions = out.excess.count();
    out.excess.dilate(1);
    if (!wPos.empty()) {
      DeviceBuffer<int> wPosD = toDevice(wPos);
      DeviceBuffer<float> wFactorD = toDevice(wFactor);
      launchWhiten(d.pix, d.width, d.height, d.nf, wPosD.get(), wFactorD.get(), static_cast<int>(wPos.size()),
                   cw, region.x0(), region.y0(), minus.sx.get(), minus.sy.get(), s);
      ST_CUDA_CHECK(cudaStreamSynchronize(s));
    }
  }
  lap("subtraction and whitening");
  if (timing)
    *timing += " (" + std::to_string(np) + " template positions, " + std::to_string(nt) + " targets)";
  out.applied = true;
  return out;
}

void zeroPixelsOnDevice(DeviceCubeRef d, const std::vector<std::uint64_t>& pixels, cudaStream_t s) {
  if (pixels.empty()) return;
  DeviceBuffer<std::uint64_t> idx = toDevice(pixels);
  launchZeroIndices(d.pix, static_cast<std::size_t>(d.nf) * d.width * d.height, idx.get(), pixels.size(), s);
  ST_CUDA_CHECK(cudaStreamSynchronize(s));
}

std::size_t zeroMaskedOnDevice(DeviceCubeRef d, const MovingMask& mask, cudaStream_t s) {
  if (mask.empty()) return 0;
  std::vector<int> xy;
  for (const auto& [x, y] : detect::maskedPositions(mask)) {
    xy.push_back(x);
    xy.push_back(y);
  }
  if (xy.empty()) return 0;
  std::vector<int> sx, sy;
  shiftsOf(mask, static_cast<std::size_t>(d.nf), sx, sy);
  DeviceBuffer<int> xyD = toDevice(xy), sxD = toDevice(sx), syD = toDevice(sy);
  DeviceBuffer<unsigned long long> count = zeros(1, s);
  launchZeroMasked(d.pix, d.width, d.height, d.nf, xyD.get(), static_cast<int>(xy.size() / 2), sxD.get(),
                   syD.get(), count.get(), s);
  return static_cast<std::size_t>(toHost(count, 1, s)[0]);
}

std::size_t zeroUnmeasuredOnDevice(DeviceCubeRef d, const std::vector<std::uint8_t>& unmeasured,
                                   const MovingMask& keep, cudaStream_t s) {
  const int w = d.width, h = d.height;
  const std::size_t np = static_cast<std::size_t>(w) * h;
  if (unmeasured.size() != np) return 0;
  const std::vector<std::uint8_t> kept = detect::coveredInSomeFrame(keep, w, h);
  std::vector<int> pixels;
  for (std::size_t i = 0; i < np; ++i)
    if (!kept[i] && unmeasured[i]) pixels.push_back(static_cast<int>(i));
  if (pixels.empty()) return 0;
  DeviceBuffer<int> pixD = toDevice(pixels);
  DeviceBuffer<unsigned long long> count = zeros(1, s);
  launchZeroUnmeasured(d.pix, np, d.nf, pixD.get(), static_cast<int>(pixels.size()), count.get(), s);
  return static_cast<std::size_t>(toHost(count, 1, s)[0]);
}

detect::SingleFrameSources zeroSingleFrameSourcesOnDevice(DeviceCubeRef d, const float* sigma, double sigmaN,
                                                          double snr, int radiusPx, const MovingMask* keep,
                                                          cudaStream_t s) {
  detect::SingleFrameSources out;
  const std::size_t nf = static_cast<std::size_t>(d.nf);
  constexpr unsigned long long kSeedCap = 1ull << 22;
  DeviceBuffer<std::uint64_t> seeds(kSeedCap);
  DeviceBuffer<unsigned long long> seedCount = zeros(1, s), perFrame = zeros(nf, s), zeroed = zeros(nf, s);
  SingleFrameLaunch p{};
  p.pix = d.pix;
  p.width = d.width;
  p.height = d.height;
  p.nf = d.nf;
  p.sigma = sigma;
  p.sigmaN = sigmaN;
  p.snr = snr;
  p.radius = radiusPx;
  DeviceBuffer<std::uint8_t> canvas;
  DeviceBuffer<int> ksx, ksy;
  if (keep && !keep->empty()) {
    std::vector<int> sx, sy;
    shiftsOf(*keep, nf, sx, sy);
    canvas = toDevice(keep->canvas());
    ksx = toDevice(sx);
    ksy = toDevice(sy);
    p.keepCanvas = canvas.get();
    p.keepCw = keep->canvasWidth();
    p.keepCh = keep->canvasHeight();
    p.keepX0 = keep->x0();
    p.keepY0 = keep->y0();
    p.keepSx = ksx.get();
    p.keepSy = ksy.get();
  }
  p.seeds = seeds.get();
  p.seedCap = kSeedCap;
  p.seedCount = seedCount.get();
  p.seedsPerFrame = perFrame.get();
  p.zeroedPerFrame = zeroed.get();
  launchSingleFrameSeeds(p, s);
  const unsigned long long n = toHost(seedCount, 1, s)[0];
  if (n > kSeedCap)
    throw GpuError("single-frame sources: " + std::to_string(n) +
                   " seeds, more than the device's list holds (" + std::to_string(kSeedCap) + ")");
  launchSingleFrameZero(p, n, s);
  const std::vector<unsigned long long> seedsH = toHost(perFrame, nf, s), zeroedH = toHost(zeroed, nf, s);
  out.seedsPerFrame.assign(seedsH.begin(), seedsH.end());
  out.zeroedPerFrame.assign(zeroedH.begin(), zeroedH.end());
  return out;
}

}  // namespace st::gpu

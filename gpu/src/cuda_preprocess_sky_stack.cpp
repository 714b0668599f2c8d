// CudaPreprocess::skyStack: the stacks at the sky rate (detect::stackAtSkyRate) that the static-source search
// and the PSF stage ask for, made from the calibrated cube prefetch() uploads behind those stages (issue 16):
// no upload of its own; the sums are the CPU's (sky_stack_kernels.cu), so the stacks are equal.
#include <vector>

#include "cuda_preprocess.hpp"
#include "resident_cube.hpp"
#include "sky_stack_kernels.hpp"
#include "st/detect/moving_mask.hpp"

namespace st::gpu {

using namespace preprocess_detail;

std::optional<detect::SkyStack> CudaPreprocess::skyStack(const FrameCube& cube, Velocity rate,
                                                         double subtract, std::size_t first,
                                                         std::size_t last) {
  if (stagewise()) return std::nullopt;
  const std::size_t nf = cube.frameCount(), np = cube.framePixels();
  if (last == 0 || last > nf) last = nf;
  const std::shared_ptr<Prefetch> pf = m_prefetch;
  if (!pf || first >= last || pf->data != cube.pixels().data() || pf->size != nf * np ||
      pf->maskSize != cube.mask().size())
    return std::nullopt;
  // Only once the upload is done: the CPU's stack (~0.1 s for 1500 x 512^2 on 16 threads) is quicker than
  // waiting for it (~0.2 s from the prefetch's start: the static-source search asks for the whole cube's
  // stack right away); its thirds and halves come later.
  if (!pf->finished.load()) return std::nullopt;
  Stopwatch sw;
  pf->join();
  if (!pf->ok || pf->key != cubeKey(cube)) return std::nullopt;
  const double waited = sw.lap();
  ST_CUDA_CHECK(cudaSetDevice(m_device.ordinal));
  DeviceResources& r = ensureResources(m_res);
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
  out.mean = Image(cw, ch);
  out.count = Image(cw, ch);
  out.max = Image(cw, ch);
  if (nc > 0) {
    ST_CUDA_CHECK(cudaMemcpyAsync(out.mean.data(), mean.get(), nc * 4, cudaMemcpyDeviceToHost, s));
    ST_CUDA_CHECK(cudaMemcpyAsync(out.count.data(), count.get(), nc * 4, cudaMemcpyDeviceToHost, s));
    ST_CUDA_CHECK(cudaMemcpyAsync(out.max.data(), mx.get(), nc * 4, cudaMemcpyDeviceToHost, s));
  }
  r.compute.sync();
  m_note = "stack at the sky rate on " + name() + " (frames " + std::to_string(first) + " to " +
           std::to_string(last) + "): join " + ms(waited) + ", " + ms(sw.lap());
  return out;
}

}  // namespace st::gpu

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "cuda_check.hpp"
#include "global_background.hpp"
#include "global_background_host.hpp"
#include "st/common/error.hpp"

namespace st::gpu {

stats::ClipStats globalBackgroundOnDevice(const FrameCube& cube, const float* pix, const std::uint8_t* mask,
                                          const stats::GlobalBackgroundParams& params, cudaStream_t stream) {
  if (cube.empty()) throw InputError("global background: the frame cube has no frames");
  // The frames of stats::globalBackground (evenly spaced).
  const std::size_t total = cube.frameCount();
  const std::size_t used = std::min(total, std::max<std::size_t>(1, params.frames));
  std::vector<int> frames;
  for (std::size_t i = 0; i < used; ++i)
    frames.push_back(static_cast<int>(used == total ? i : (i * total) / used));
  // The clip's shift: the first sample in the CPU's gathering order.
  const std::size_t np = cube.framePixels();
  const auto& hostMask = cube.mask();
  bool found = false;
  double shift = 0.0;
  for (std::size_t k = 0; k < frames.size() && !found; ++k) {
    const std::size_t base = static_cast<std::size_t>(frames[k]) * np;
    const float* f = cube.frame(static_cast<std::size_t>(frames[k]));
    for (std::size_t i = 0; i < np; ++i) {
      if ((!hostMask.empty() && hostMask[base + i]) || !std::isfinite(f[i])) continue;
      shift = f[i];
      found = true;
      break;
    }
  }
  if (!found) {
    throw InputError("global background: every pixel of the " + std::to_string(frames.size()) +
                     " frames used is masked (first file: " + cube.info().front().file + ")");
  }
  DeviceBuffer<int> framesD = toDevice(frames);
  DeviceBuffer<double> s(kGlobalMomentBlocks), ss(kGlobalMomentBlocks);
  DeviceBuffer<unsigned long long> c(kGlobalMomentBlocks);
  std::vector<double> sH(kGlobalMomentBlocks), ssH(kGlobalMomentBlocks);
  std::vector<unsigned long long> cH(kGlobalMomentBlocks);
  GlobalMomentsLaunch p{pix, mask, framesD.get(), static_cast<int>(frames.size()), np,
                        std::numeric_limits<double>::infinity(), shift, s.get(), ss.get(), c.get()};
  // stats/sigma_clip.cpp clip(), one-sided, 100 iterations at most.
  stats::ClipStats out;
  std::size_t previous = std::numeric_limits<std::size_t>::max();
  for (int it = 1; it <= 100; ++it) {
    launchGlobalMoments(p, stream);
    ST_CUDA_CHECK(cudaMemcpyAsync(sH.data(), s.get(), sH.size() * 8, cudaMemcpyDeviceToHost, stream));
    ST_CUDA_CHECK(cudaMemcpyAsync(ssH.data(), ss.get(), ssH.size() * 8, cudaMemcpyDeviceToHost, stream));
    ST_CUDA_CHECK(cudaMemcpyAsync(cH.data(), c.get(), cH.size() * 8, cudaMemcpyDeviceToHost, stream));
    ST_CUDA_CHECK(cudaStreamSynchronize(stream));
    double sum = 0.0, sumSq = 0.0;
    std::size_t n = 0;
    for (int b = 0; b < kGlobalMomentBlocks; ++b) {
      sum += sH[b];
      sumSq += ssH[b];
      n += cH[b];
    }
    out.iterations = it;
    out.count = n;
    if (n == 0) break;
    const double meanShifted = sum / static_cast<double>(n);
    out.mean = shift + meanShifted;
    out.sigma = n > 1 ? std::sqrt(std::max(0.0, (sumSq - sum * meanShifted) / static_cast<double>(n - 1))) : 0.0;
    if (n == previous) {
      out.converged = true;
      break;
    }
    previous = n;
    p.hi = out.mean + params.xi * out.sigma;
  }
  return out;
}

}  // namespace st::gpu

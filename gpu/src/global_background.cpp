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

namespace {

/// The frames stats::globalBackground uses (evenly spaced) and its clip's shift (the first sample in its
/// gathering order); st::InputError when every sample is masked.
/// With `devicePix` (the cube on the device, frame-major) the frames' values are read from there: the host
/// cube's may still be downloading (the frame backgrounds' download behind the stages after it).
std::vector<int> framesAndShift(const FrameCube& cube, const stats::GlobalBackgroundParams& params,
                                double& shift, const float* devicePix = nullptr,
                                cudaStream_t stream = nullptr) {
  if (cube.empty()) throw InputError("global background: the frame cube has no frames");
  const std::size_t total = cube.frameCount();
  const std::size_t used = std::min(total, std::max<std::size_t>(1, params.frames));
  std::vector<int> frames;
  for (std::size_t i = 0; i < used; ++i)
    frames.push_back(static_cast<int>(used == total ? i : (i * total) / used));
  const std::size_t np = cube.framePixels();
  const auto& hostMask = cube.mask();
  std::vector<float> copied;
  for (const int n : frames) {
    const std::size_t base = static_cast<std::size_t>(n) * np;
    const float* f = cube.frame(static_cast<std::size_t>(n));
    if (devicePix) {
      copied.resize(np);
      ST_CUDA_CHECK(cudaMemcpyAsync(copied.data(), devicePix + base, np * sizeof(float),
                                    cudaMemcpyDeviceToHost,
                                    stream));  // after the work queued on `stream` that wrote it
      ST_CUDA_CHECK(cudaStreamSynchronize(stream));
      f = copied.data();
    }
    for (std::size_t i = 0; i < np; ++i) {
      if ((!hostMask.empty() && hostMask[base + i]) || !std::isfinite(f[i])) continue;
      shift = f[i];
      return frames;
    }
  }
  throw InputError("global background: every pixel of the " + std::to_string(frames.size()) +
                   " frames used is masked (first file: " + cube.info().front().file + ")");
}

/// stats/sigma_clip.cpp clip(), one-sided, 100 iterations at most, over frames[0..nFrames) of `pix`.
stats::ClipStats clip(const float* pix, const std::uint8_t* mask, const std::vector<int>& frames,
                      std::size_t np, double shift, double xi, cudaStream_t stream) {
  DeviceBuffer<int> framesD = toDevice(frames);
  DeviceBuffer<double> s(kGlobalMomentBlocks), ss(kGlobalMomentBlocks);
  DeviceBuffer<unsigned long long> c(kGlobalMomentBlocks);
  std::vector<double> sH(kGlobalMomentBlocks), ssH(kGlobalMomentBlocks);
  std::vector<unsigned long long> cH(kGlobalMomentBlocks);
  GlobalMomentsLaunch p{pix,
                        mask,
                        framesD.get(),
                        static_cast<int>(frames.size()),
                        np,
                        std::numeric_limits<double>::infinity(),
                        shift,
                        s.get(),
                        ss.get(),
                        c.get()};
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
    out.sigma =
        n > 1 ? std::sqrt(std::max(0.0, (sumSq - sum * meanShifted) / static_cast<double>(n - 1))) : 0.0;
    if (n == previous) {
      out.converged = true;
      break;
    }
    previous = n;
    p.hi = out.mean + xi * out.sigma;
  }
  return out;
}

}  // namespace

stats::ClipStats globalBackgroundOnDevice(const FrameCube& cube, const float* pix, const std::uint8_t* mask,
                                          const stats::GlobalBackgroundParams& params, cudaStream_t stream) {
  double shift = 0.0;
  const std::vector<int> frames = framesAndShift(cube, params, shift, pix, stream);
  return clip(pix, mask, frames, cube.framePixels(), shift, params.xi, stream);
}

stats::ClipStats globalBackgroundUploaded(const FrameCube& cube, const stats::GlobalBackgroundParams& params,
                                          cudaStream_t stream) {
  double shift = 0.0;
  const std::vector<int> frames = framesAndShift(cube, params, shift);
  const std::size_t np = cube.framePixels();
  const bool hasMask = cube.mask().size() == cube.pixels().size();
  DeviceBuffer<float> pix(frames.size() * np);
  DeviceBuffer<std::uint8_t> mask(hasMask ? frames.size() * np : 0);
  std::vector<int> compact(frames.size());
  for (std::size_t k = 0; k < frames.size(); ++k) {
    const std::size_t n = static_cast<std::size_t>(frames[k]);
    ST_CUDA_CHECK(cudaMemcpyAsync(pix.get() + k * np, cube.frame(n), np * sizeof(float),
                                  cudaMemcpyHostToDevice, stream));
    if (hasMask)
      ST_CUDA_CHECK(cudaMemcpyAsync(mask.get() + k * np, cube.mask().data() + n * np, np,
                                    cudaMemcpyHostToDevice, stream));
    compact[k] = static_cast<int>(k);
  }
  return clip(pix.get(), hasMask ? mask.get() : nullptr, compact, np, shift, params.xi, stream);
}

}  // namespace st::gpu

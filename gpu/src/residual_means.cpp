#include <algorithm>
#include <cmath>
#include <functional>
#include <vector>

#include "cuda_check.hpp"
#include "residual_means.hpp"
#include "residual_means_host.hpp"

namespace st::gpu {

double removeResidualMeansOnDevice(float* pix, int width, int height, int nf, int meshPx, double clipSigma,
                                   cudaStream_t stream, int framesPerChunk,
                                   const std::function<void(int, int)>& chunkDone) {
  const int mesh = std::max(8, meshPx);
  const int nx = (width + mesh - 1) / mesh, ny = (height + mesh - 1) / mesh;
  const std::size_t cells = static_cast<std::size_t>(nx) * ny;
  if (nf <= 0 || cells == 0) return 0.0;
  const int chunk = framesPerChunk > 0 ? std::min(framesPerChunk, nf) : nf;
  const std::size_t np = static_cast<std::size_t>(width) * height;
  DeviceBuffer<double> means(static_cast<std::size_t>(chunk) * cells);
  DeviceBuffer<unsigned char> skipD(static_cast<std::size_t>(chunk));
  // Per chunk of frames: their cell means, the host's fill, the subtraction; the host buffers of each chunk
  // kept until the end (their uploads are asynchronous).
  std::vector<std::vector<double>> meansH;
  std::vector<std::vector<unsigned char>> skipH;
  std::vector<double> sumSq(static_cast<std::size_t>(nf), 0.0);
  std::size_t counted = 0;
  std::vector<double> good;
  for (int f0 = 0; f0 < nf; f0 += chunk) {
    const int f1 = std::min(nf, f0 + chunk), n = f1 - f0;
    float* part = pix + static_cast<std::size_t>(f0) * np;
    const ResidualMeansLaunch p{
        part,
        width,
        height,
        n,
        mesh,
        nx,
        ny,
        clipSigma,
        static_cast<int>(std::max<std::size_t>(32, static_cast<std::size_t>(mesh) * mesh / 16)),
        means.get()};
    launchResidualCellMeans(p, stream);
    std::vector<double>& m = meansH.emplace_back(static_cast<std::size_t>(n) * cells);
    ST_CUDA_CHECK(
        cudaMemcpyAsync(m.data(), means.get(), m.size() * sizeof(double), cudaMemcpyDeviceToHost, stream));
    ST_CUDA_CHECK(cudaStreamSynchronize(stream));
    // Per frame, as core/stats/noise_model.cpp: cells without a mean take the median of the frame's others; a
    // frame without any is left alone; the rms over every cell of the frames that have one.
    std::vector<unsigned char>& skip = skipH.emplace_back(static_cast<std::size_t>(n), 0);
    for (int k = 0; k < n; ++k) {
      double* frame = m.data() + static_cast<std::size_t>(k) * cells;
      good.clear();
      for (std::size_t c = 0; c < cells; ++c)
        if (std::isfinite(frame[c])) good.push_back(frame[c]);
      if (good.empty()) {
        skip[static_cast<std::size_t>(k)] = 1;
        continue;
      }
      const auto mid = good.begin() + static_cast<std::ptrdiff_t>(good.size() / 2);
      std::nth_element(good.begin(), mid, good.end());
      const double fill = *mid;
      for (std::size_t c = 0; c < cells; ++c) {
        if (!std::isfinite(frame[c])) frame[c] = fill;
        sumSq[static_cast<std::size_t>(f0 + k)] += frame[c] * frame[c];
        ++counted;
      }
    }
    ST_CUDA_CHECK(
        cudaMemcpyAsync(means.get(), m.data(), m.size() * sizeof(double), cudaMemcpyHostToDevice, stream));
    ST_CUDA_CHECK(cudaMemcpyAsync(skipD.get(), skip.data(), skip.size(), cudaMemcpyHostToDevice, stream));
    launchResidualSubtract(part, width, height, n, mesh, nx, ny, means.get(), skipD.get(), stream);
    if (chunkDone) chunkDone(f0, f1);
  }
  ST_CUDA_CHECK(cudaStreamSynchronize(stream));
  double s = 0.0;
  for (const double v : sumSq)
    s += v;
  return counted > 0 ? std::sqrt(s / static_cast<double>(counted)) : 0.0;
}

}  // namespace st::gpu

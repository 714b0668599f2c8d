#include <algorithm>
#include <cmath>
#include <functional>
#include <vector>

#include "cuda_check.hpp"
#include "residual_means.hpp"
#include "residual_means_host.hpp"
#include "st/common/trace.hpp"

namespace st::gpu {

double removeResidualMeansOnDevice(float* pix, int width, int height, int nf, int meshPx, double clipSigma,
                                   cudaStream_t stream, int framesPerChunk,
                                   const std::function<void(int, int)>& chunkDone, void* pinned,
                                   std::size_t pinnedBytes) {
  const int mesh = std::max(8, meshPx);
  const int nx = (width + mesh - 1) / mesh, ny = (height + mesh - 1) / mesh;
  const std::size_t cells = static_cast<std::size_t>(nx) * ny;
  if (nf <= 0 || cells == 0) return 0.0;
  const int chunk = framesPerChunk > 0 ? std::min(framesPerChunk, nf) : nf;
  const std::size_t np = static_cast<std::size_t>(width) * height;
  const int minCount =
      static_cast<int>(std::max<std::size_t>(32, static_cast<std::size_t>(mesh) * mesh / 16));
  std::vector<double> sumSq(static_cast<std::size_t>(nf), 0.0);
  std::size_t counted = 0;
  std::vector<double> good;
  // Per frame, as core/stats/noise_model.cpp: cells without a mean take the median of the frame's others; a
  // frame without any is left alone (skip); the rms over every cell of the frames that have one.
  const auto fill = [&](double* m, unsigned char* skip, int f0, int n) {
    for (int k = 0; k < n; ++k) {
      double* frame = m + static_cast<std::size_t>(k) * cells;
      skip[k] = 0;
      good.clear();
      for (std::size_t c = 0; c < cells; ++c)
        if (std::isfinite(frame[c])) good.push_back(frame[c]);
      if (good.empty()) {
        skip[k] = 1;
        continue;
      }
      const auto mid = good.begin() + static_cast<std::ptrdiff_t>(good.size() / 2);
      std::nth_element(good.begin(), mid, good.end());
      const double fillValue = *mid;
      for (std::size_t c = 0; c < cells; ++c) {
        if (!std::isfinite(frame[c])) frame[c] = fillValue;
        sumSq[static_cast<std::size_t>(f0 + k)] += frame[c] * frame[c];
        ++counted;
      }
    }
  };
  const auto cellMeans = [&](int f0, int n, double* out) {
    const ResidualMeansLaunch p{
        pix + static_cast<std::size_t>(f0) * np, width, height, n, mesh, nx, ny, clipSigma, minCount, out};
    launchResidualCellMeans(p, stream);
  };
  const std::size_t meansBytes = static_cast<std::size_t>(chunk) * cells * sizeof(double);
  const std::size_t slot = (meansBytes + static_cast<std::size_t>(chunk) + 255) / 256 * 256;
  const bool pipelined =
      framesPerChunk > 0 && pinned && 2 * slot <= pinnedBytes && !envKnob("ST_GPU_RESIDUAL_MEANS_SERIAL");
  if (pipelined) {
    // Two slots of pinned memory and two device buffers, alternating by chunk: chunk k + 1's means are
    // queued before the host fills chunk k's, whose subtraction (and chunkDone's download) follows them.
    DeviceBuffer<double> meansD[2] = {DeviceBuffer<double>(static_cast<std::size_t>(chunk) * cells),
                                      DeviceBuffer<double>(static_cast<std::size_t>(chunk) * cells)};
    DeviceBuffer<unsigned char> skipD[2] = {DeviceBuffer<unsigned char>(static_cast<std::size_t>(chunk)),
                                            DeviceBuffer<unsigned char>(static_cast<std::size_t>(chunk))};
    const auto hostMeans = [&](int b) {
      return reinterpret_cast<double*>(static_cast<char*>(pinned) + static_cast<std::size_t>(b) * slot);
    };
    const auto hostSkip = [&](int b) {
      return reinterpret_cast<unsigned char*>(static_cast<char*>(pinned) +
                                              static_cast<std::size_t>(b) * slot + meansBytes);
    };
    Event ready[2];
    const int chunks = (nf + chunk - 1) / chunk;
    const auto queueMeans = [&](int k) {
      const int f0 = k * chunk, n = std::min(nf, f0 + chunk) - f0, b = k & 1;
      cellMeans(f0, n, meansD[b].get());
      ST_CUDA_CHECK(cudaMemcpyAsync(hostMeans(b), meansD[b].get(), static_cast<std::size_t>(n) * cells * 8,
                                    cudaMemcpyDeviceToHost, stream));
      ready[b].record(stream);
    };
    queueMeans(0);
    for (int k = 0; k < chunks; ++k) {
      const int f0 = k * chunk, f1 = std::min(nf, f0 + chunk), n = f1 - f0, b = k & 1;
      if (k + 1 < chunks) queueMeans(k + 1);
      {
        const trace::Scope traced("residual means: waits for a chunk's cell means");
        ready[b].sync();
      }
      fill(hostMeans(b), hostSkip(b), f0, n);
      ST_CUDA_CHECK(cudaMemcpyAsync(meansD[b].get(), hostMeans(b), static_cast<std::size_t>(n) * cells * 8,
                                    cudaMemcpyHostToDevice, stream));
      ST_CUDA_CHECK(cudaMemcpyAsync(skipD[b].get(), hostSkip(b), static_cast<std::size_t>(n),
                                    cudaMemcpyHostToDevice, stream));
      launchResidualSubtract(pix + static_cast<std::size_t>(f0) * np, width, height, n, mesh, nx, ny,
                             meansD[b].get(), skipD[b].get(), stream);
      if (chunkDone) chunkDone(f0, f1);
    }
    ST_CUDA_CHECK(cudaStreamSynchronize(stream));  // before the buffers and the pinned slots are let go
  } else {
    DeviceBuffer<double> means(static_cast<std::size_t>(chunk) * cells);
    DeviceBuffer<unsigned char> skipD(static_cast<std::size_t>(chunk));
    // Per chunk of frames: their cell means, the host's fill, the subtraction; the host buffers of each
    // chunk kept until the end (their uploads are asynchronous).
    std::vector<std::vector<double>> meansH;
    std::vector<std::vector<unsigned char>> skipH;
    for (int f0 = 0; f0 < nf; f0 += chunk) {
      const int f1 = std::min(nf, f0 + chunk), n = f1 - f0;
      cellMeans(f0, n, means.get());
      std::vector<double>& m = meansH.emplace_back(static_cast<std::size_t>(n) * cells);
      ST_CUDA_CHECK(
          cudaMemcpyAsync(m.data(), means.get(), m.size() * sizeof(double), cudaMemcpyDeviceToHost, stream));
      ST_CUDA_CHECK(cudaStreamSynchronize(stream));
      std::vector<unsigned char>& skip = skipH.emplace_back(static_cast<std::size_t>(n), 0);
      fill(m.data(), skip.data(), f0, n);
      ST_CUDA_CHECK(
          cudaMemcpyAsync(means.get(), m.data(), m.size() * sizeof(double), cudaMemcpyHostToDevice, stream));
      ST_CUDA_CHECK(cudaMemcpyAsync(skipD.get(), skip.data(), skip.size(), cudaMemcpyHostToDevice, stream));
      launchResidualSubtract(pix + static_cast<std::size_t>(f0) * np, width, height, n, mesh, nx, ny,
                             means.get(), skipD.get(), stream);
      if (chunkDone) chunkDone(f0, f1);
    }
    ST_CUDA_CHECK(cudaStreamSynchronize(stream));
  }
  double s = 0.0;
  for (const double v : sumSq)
    s += v;
  return counted > 0 ? std::sqrt(s / static_cast<double>(counted)) : 0.0;
}

}  // namespace st::gpu

// The host side of SEP's background on the device (frame_backgrounds.hpp): per frame, SEP's filterback and
// makebackspline on the meshes the device measured, and the constants of its spline evaluation per row and
// column, all from core (st/stats/sep_background.hpp, SEP's arithmetic step by step, the CPU path's own), so
// the spline nodes and the global level and rms are SEP's for the same mesh values.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <vector>

#include "cuda_check.hpp"
#include "frame_backgrounds.hpp"
#include "st/common/parallel.hpp"

namespace st::gpu {

SepFrameBackgrounds removeFrameBackgroundsOnDevice(float* pix, const std::uint8_t* mask, int width,
                                                   int height, int nf, int meshPx, int filterCells,
                                                   cudaStream_t stream, int framesPerChunk,
                                                   const std::function<void(int, int)>& chunkReady) {
  using clock = std::chrono::steady_clock;
  SepFrameBackgrounds out;
  out.level.assign(static_cast<std::size_t>(nf), std::nan(""));
  out.rms.assign(static_cast<std::size_t>(nf), std::nan(""));
  if (nf <= 0 || width <= 0 || height <= 0) return out;
  const stats::sep::MeshGrid grid = stats::sep::meshGrid(width, height, meshPx);
  const int filter = std::max(1, filterCells);
  const int bw = grid.bw, bh = grid.bh, nx = grid.nx, ny = grid.ny;
  const std::size_t nb = static_cast<std::size_t>(nx) * ny;
  auto t0 = clock::now();
  DeviceBuffer<float> back(static_cast<std::size_t>(nf) * nb), sigma(static_cast<std::size_t>(nf) * nb);
  // Each chunk's meshes once chunkReady has queued what they need on the stream (its frames' upload).
  const int chunk = framesPerChunk > 0 ? std::min(framesPerChunk, nf) : nf;
  const std::size_t np = static_cast<std::size_t>(width) * height;
  for (int f0 = 0; f0 < nf; f0 += chunk) {
    const int f1 = std::min(nf, f0 + chunk);
    if (chunkReady) chunkReady(f0, f1);
    const std::size_t at = static_cast<std::size_t>(f0);
    SepMeshLaunch m{pix + at * np,
                    mask ? mask + at * np : nullptr,
                    width,
                    height,
                    f1 - f0,
                    bw,
                    bh,
                    nx,
                    ny,
                    stats::sep::histogramStep(),
                    back.get() + at * nb,
                    sigma.get() + at * nb};
    launchSepMeshes(m, stream);
  }
  std::vector<float> b(back.size()), s(sigma.size()), db(back.size());
  ST_CUDA_CHECK(
      cudaMemcpyAsync(b.data(), back.get(), b.size() * sizeof(float), cudaMemcpyDeviceToHost, stream));
  ST_CUDA_CHECK(
      cudaMemcpyAsync(s.data(), sigma.get(), s.size() * sizeof(float), cudaMemcpyDeviceToHost, stream));
  ST_CUDA_CHECK(cudaStreamSynchronize(stream));
  auto t1 = clock::now();
  out.meshSeconds = std::chrono::duration<double>(t1 - t0).count();
  parallelFor(static_cast<std::size_t>(nf), 16, [&](std::size_t lo, std::size_t hi) {
    for (std::size_t n = lo; n < hi; ++n) {
      float global = 0.0f, globalrms = 0.0f;
      stats::sep::filterback(nx, ny, filter, filter, b.data() + n * nb, s.data() + n * nb, global, globalrms);
      stats::sep::makebackspline(nx, ny, b.data() + n * nb, db.data() + n * nb);
      out.level[n] = global;
      out.rms[n] = globalrms;
    }
  });
  std::vector<double> levels;
  for (const double l : out.level)
    if (std::isfinite(l)) levels.push_back(l);
  if (!levels.empty()) {
    const auto mid = levels.begin() + static_cast<std::ptrdiff_t>(levels.size() / 2);
    std::nth_element(levels.begin(), mid, levels.end());
    out.restored = *mid;
  }
  const std::vector<SepRow> rows = stats::sep::rowTable(height, bh, ny);
  const std::vector<SepColumn> cols = stats::sep::columnTable(width, bw, nx);
  auto t2 = clock::now();
  out.hostSeconds = std::chrono::duration<double>(t2 - t1).count();
  DeviceBuffer<float> dback(db.size());
  ST_CUDA_CHECK(
      cudaMemcpyAsync(back.get(), b.data(), b.size() * sizeof(float), cudaMemcpyHostToDevice, stream));
  ST_CUDA_CHECK(
      cudaMemcpyAsync(dback.get(), db.data(), db.size() * sizeof(float), cudaMemcpyHostToDevice, stream));
  DeviceBuffer<SepRow> rowsD = toDevice(rows);
  DeviceBuffer<SepColumn> colsD = toDevice(cols);
  SepSubtractLaunch sub{pix,
                        width,
                        height,
                        nf,
                        nx,
                        ny,
                        back.get(),
                        dback.get(),
                        rowsD.get(),
                        colsD.get(),
                        static_cast<float>(out.restored)};
  launchSepSubtract(sub, stream);
  ST_CUDA_CHECK(cudaStreamSynchronize(stream));
  out.subtractSeconds = std::chrono::duration<double>(clock::now() - t2).count();
  return out;
}

}  // namespace st::gpu

#include "st/search/cpu_backend.hpp"

#include <algorithm>
#include <chrono>
#include <string>

#include "ipsa_kernel.hpp"
#include "st/common/error.hpp"
#include "st/common/parallel.hpp"
#include "st/search/candidates.hpp"
#include "st/search/ipsa.hpp"
#include "st/search/search_run.hpp"
#include "st/search/velocity_grid.hpp"

namespace st::search {

namespace {

class CpuBackend final : public SearchBackend {
 public:
  [[nodiscard]] std::string name() const override {
    return "cpu (" + std::to_string(workerCount()) + " threads)";
  }

  SearchResult search(const FilteredCube& cube, const VelocityGrid& grid, const SearchParams& params,
                      ProgressSink& progress, CancelToken& cancel) override {
    const auto start = std::chrono::steady_clock::now();
    validateSearchInput(cube, grid, params);
    SearchResult result;
    result.grid = grid;
    result.trials = trialCounts(cube.frames.width(), cube.frames.height(), grid);
    result.snrThreshold = effectiveThreshold(params, result.trials);
    result.minFrames = minFramesFor(params, cube.frames.frameCount());
    result.tRefMjd = cube.frames.tRefMjd();
    result.backend = "cpu";
    result.method = "exact";

    detail::KernelParams kp;
    kp.sigmaF = cube.sigmaF;
    kp.snrThreshold = result.snrThreshold;
    kp.minFrames = result.minFrames;
    kp.maxHits = params.maxCandidates;
    const detail::Roi roi{0, 0, cube.frames.width(), cube.frames.height()};
    detail::KernelOutput out = detail::runIpsaKernel(cube.frames, grid, roi, kp, progress, cancel);

    std::sort(out.hits.begin(), out.hits.end(),
              [](const CellHit& a, const CellHit& b) { return a.snr > b.snr; });
    if (out.hits.size() > params.maxCandidates) out.hits.resize(params.maxCandidates);
    result.candidates = clusterCells(out.hits, grid, defaultClusterParams(cube.psfFwhmPx), result.trials);
    result.map = std::move(out.map);
    result.cellsAboveThreshold = out.hitsTotal;
    result.elapsedS = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    progress.report(1.0, "velocity search");
    return result;
  }

  Image stackAt(const FilteredCube& cube, Velocity v, StackMode mode) override {
    if (mode == StackMode::Csa) throw InputError("CSA not supported by this backend");
    const FrameCube& f = cube.frames;
    if (f.frameCount() == 0) throw InputError("cannot stack a cube with no frames");
    const int w = f.width();
    const int h = f.height();
    Image out(w, h, 0.0f);
    const std::vector<double> dt = f.timeOffsetsS();
    for (std::size_t n = 0; n < f.frameCount(); ++n) {
      const int sx = ipsaShift(v.vx, dt[n]);
      const int sy = ipsaShift(v.vy, dt[n]);
      // out(x, y) += F_n(x + sx, y + sy) where the sample is inside the frame.
      const int x0 = std::max(0, -sx);
      const int x1 = std::min(w, w - sx);
      const int y0 = std::max(0, -sy);
      const int y1 = std::min(h, h - sy);
      const float* src = f.frame(n);
      for (int y = y0; y < y1; ++y) {
        float* o = out.data() + static_cast<std::size_t>(y) * w;
        const float* s = src + static_cast<std::size_t>(y + sy) * w + sx;
        for (int x = x0; x < x1; ++x)
          o[x] += s[x];
      }
    }
    return out;
  }
};

}  // namespace

std::unique_ptr<SearchBackend> makeCpuBackend() {
  return std::make_unique<CpuBackend>();
}

}  // namespace st::search

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
#include "st/search/tree_search.hpp"
#include "st/search/velocity_grid.hpp"
#include "st/stack/ipsa.hpp"

namespace st::search {

namespace {

class CpuBackend final : public SearchBackend {
 public:
  [[nodiscard]] std::string name() const override {
    return "cpu (" + std::to_string(workerCount()) + " threads)";
  }

  SearchResult search(const FilteredCube& cube, const VelocityGrid& grid, const SearchParams& params,
                      ProgressSink& progress, CancelToken& cancel) override {
    if (params.method == SearchMethod::Tree) return treeSearch(cube, grid, params, progress, cancel);
    if (params.method != SearchMethod::Exact) {
      throw InputError("search method '" + std::string(params.method.name()) + "' (expected exact or tree)");
    }
    const auto start = std::chrono::steady_clock::now();
    SearchResult result = startSearchResult(cube, grid, params, "cpu", SearchMethod::Exact);

    detail::KernelParams kp;
    kp.sigmaF = cube.sigmaF;
    kp.snrThreshold = result.snrThreshold;
    kp.minFrames = result.minFrames;
    kp.maxHits = params.maxCandidates;
    const detail::Roi roi{0, 0, cube.frames.width(), cube.frames.height()};
    detail::KernelOutput out = detail::runIpsaKernel(cube.frames, grid, roi, kp, progress, cancel);

    setCandidates(result, std::move(out.hits), cube, params);
    result.map = std::move(out.map);
    result.cellsAboveThreshold = out.hitsTotal;
    result.elapsedS = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    progress.report(1.0, "velocity search");
    return result;
  }

  [[nodiscard]] bool supportsMethod(const std::string& method) const override {
    return method == "exact" || method == "tree";
  }

  Image stackAt(const FilteredCube& cube, Velocity v, StackMode mode) override {
    // CSA (sub-pixel shifts, paper §2.2) is not part of st::stack yet.
    if (mode == StackMode::Csa) throw InputError("CSA not supported by this backend");
    return stack::stackIpsa(cube.frames, v).sum;
  }
};

}  // namespace

std::unique_ptr<SearchBackend> makeCpuBackend() {
  return std::make_unique<CpuBackend>();
}

}  // namespace st::search

#include "st/search/method_choice.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "st/common/error.hpp"
#include "st/common/parallel.hpp"
#include "st/search/tree_plan.hpp"
#include "st/search/tree_search.hpp"
#include "st/search/velocity_grid.hpp"

namespace st::search {

namespace {

// CPU coefficients (fit: see the header and README "Performance").
constexpr double kCpuTreeOpsWeight = 9.6;
constexpr double kCpuTreeFixedS = 0.013;
constexpr double kCpuExactFixedS = 0.003;
constexpr double kCpuExactWidthPx = 128.0;

// CUDA, H100 (README): exact 9.8e12 additions/s of the stair kernel, 0.45-0.47 s end to end for the paper
// problem (4e12 additions); tree 36 ms of kernels + ~80 ms upload, 0.20-0.21 s end to end for the same
// problem (1.22e10 additions of the CPU plan): ~0.12 s fixed + 1.22e10 additions in ~0.085 s.
constexpr double kCudaExactAdditionsPerS = 9.5e12;
constexpr double kCudaExactFixedS = 0.05;
constexpr double kCudaTreeAdditionsPerS = 1.22e10 / 0.085;
constexpr double kCudaTreeFixedS = 0.12;

std::string formatSeconds(double s) {
  char text[32];
  if (!std::isfinite(s)) return "n/a";
  if (s < 1.0)
    std::snprintf(text, sizeof text, "%.0f ms", s * 1e3);
  else if (s < 120.0)
    std::snprintf(text, sizeof text, "%.1f s", s);
  else
    std::snprintf(text, sizeof text, "%.1f min", s / 60.0);
  return text;
}

std::string autoReason(const char* verdict, const MethodEstimate& e) {
  char text[256];
  std::snprintf(text, sizeof text, "auto: %s (estimated exact %s, tree %s; %.0fx fewer additions)", verdict,
                formatSeconds(e.exactSeconds).c_str(), formatSeconds(e.treeSeconds).c_str(),
                e.treeAdditions > 0.0 ? e.exactAdditions / e.treeAdditions : 0.0);
  return text;
}

}  // namespace

MethodCostModel cpuCostModel(unsigned threads, std::optional<double> exactAdditionsPerS) {
  MethodCostModel m;
  m.exactAdditionsPerS = exactAdditionsPerS.value_or(kCpuAdditionsPerSecondPerThread *
                                                     static_cast<double>(std::max(1u, threads)));
  m.exactFixedS = kCpuExactFixedS;
  m.exactWidthPx = kCpuExactWidthPx;
  m.treeOpsWeight = kCpuTreeOpsWeight;
  m.treeFixedS = kCpuTreeFixedS;
  return m;
}

MethodCostModel cudaCostModel() {
  MethodCostModel m;
  m.exactAdditionsPerS = kCudaExactAdditionsPerS;
  m.exactFixedS = kCudaExactFixedS;
  m.treeOpsWeight = kCudaExactAdditionsPerS / kCudaTreeAdditionsPerS;
  m.treeFixedS = kCudaTreeFixedS;
  return m;
}

MethodCostModel costModelFor(const SearchBackend& backend) {
  if (backend.name().rfind("cuda", 0) == 0) return cudaCostModel();
  return cpuCostModel(workerCount());
}

void priceMethods(MethodEstimate& e, const MethodCostModel& model) {
  double efficiency = 1.0;
  if (model.exactWidthPx > 0.0 && e.width > 0) {
    const double w = static_cast<double>(e.width);
    efficiency = std::min(1.0, (512.0 + model.exactWidthPx) / 512.0 * w / (w + model.exactWidthPx));
  }
  e.exactSeconds = model.exactFixedS + e.exactAdditions / (model.exactAdditionsPerS * efficiency);
  e.treeSeconds = e.treeAdditions > 0.0
                      ? model.treeFixedS + model.treeOpsWeight * e.treeAdditions / model.exactAdditionsPerS
                      : std::numeric_limits<double>::infinity();
}

MethodEstimate estimateMethods(int width, int height, const std::vector<double>& dtS,
                               const VelocityGrid& grid, const MethodCostModel& model, unsigned threads,
                               std::size_t bufferBytes) {
  MethodEstimate e;
  const SearchEstimate exact =
      estimateSearch(width, height, dtS.size(), grid, std::max(1u, threads), model.exactAdditionsPerS);
  e.exactAdditions = exact.additions;
  e.exactWorkingBytes = exact.workingBytes;
  e.cubeBytes = exact.cubeBytes;
  e.width = width;
  priceMethods(e, model);
  const bool distinctTimes = dtS.size() >= 2 && *std::max_element(dtS.begin(), dtS.end()) >
                                                    *std::min_element(dtS.begin(), dtS.end());
  if (!distinctTimes || grid.count() == 0 || !(grid.stepPxS > 0.0) || width <= 0 || height <= 0) return e;
  const TreePlan plan = buildTreePlan(dtS, grid);
  e.treeTileRows = treeTileRows(plan, width, treeTileBudgetPerThread(threads, bufferBytes));
  e.treeAdditions = treeAdditions(plan, width, height, e.treeTileRows);
  e.treeMaxShiftErrorPx = std::max(plan.maxAbsErrX, plan.maxAbsErrY);
  priceMethods(e, model);
  // Every thread holds one tile's partial stacks; there are no more busy threads than tiles.
  const std::size_t tiles = static_cast<std::size_t>((height + e.treeTileRows - 1) / e.treeTileRows);
  const std::size_t busy = std::min<std::size_t>(std::max(1u, threads), tiles);
  e.treeWorkingBytes =
      busy * treeTileBytes(plan, width, e.treeTileRows) + 12 * grid.count() +
      static_cast<std::size_t>(width + height) * static_cast<std::size_t>(grid.nvx + grid.nvy) * 8;
  return e;
}

MethodChoice chooseMethod(const std::string& requested, const MethodEstimate& estimate, bool treeSupported,
                          const std::string& backendName) {
  if (requested == "exact") return {"exact", "requested"};
  if (requested == "tree") {
    if (!treeSupported) {
      throw InputError("the tree search is not available on the backend '" + backendName +
                       "': use the CPU backend, or method exact or auto");
    }
    return {"tree", "requested"};
  }
  if (requested != "auto") {
    throw InputError("unknown search method '" + requested + "' (expected auto, exact or tree)");
  }
  if (!treeSupported) return {"exact", "auto: exact, the backend '" + backendName + "' has no tree search"};
  const MethodEstimate& e = estimate;
  if (!std::isfinite(e.treeSeconds)) return {"exact", "auto: exact, no tree plan for these frames"};
  if (e.exactSeconds < kAutoTreeMinSpeedup * e.treeSeconds)
    return {"exact", autoReason("exact, the tree would not be clearly faster", e)};
  if (e.exactSeconds - e.treeSeconds < kAutoTreeMinSavingS)
    return {"exact", autoReason("exact, too small for the tree's SNR loss to pay", e)};
  return {"tree", autoReason("tree, clearly faster", e)};
}

MethodChoice resolveMethod(const SearchBackend& backend, const FilteredCube& cube, const VelocityGrid& grid,
                           const std::string& requested, MethodEstimate* estimate) {
  MethodEstimate e;
  const bool treeSupported = backend.supportsMethod("tree");
  // Only "auto" needs the estimate (a tree plan: milliseconds even for the paper problem).
  if (requested == "auto" && treeSupported) {
    e = estimateMethods(cube.frames.width(), cube.frames.height(), cube.frames.timeOffsetsS(), grid,
                        costModelFor(backend), workerCount());
  }
  if (estimate) *estimate = e;
  return chooseMethod(requested, e, treeSupported, backend.name());
}

SearchResult searchWithChoice(SearchBackend& backend, const FilteredCube& cube, const VelocityGrid& grid,
                              const SearchParams& params, const MethodChoice& choice, ProgressSink& progress,
                              CancelToken& cancel) {
  SearchParams resolved = params;
  resolved.method = choice.method;
  SearchResult result = backend.search(cube, grid, resolved, progress, cancel);
  result.method = choice.method;
  result.methodReason = choice.reason;
  return result;
}

SearchResult searchWithMethod(SearchBackend& backend, const FilteredCube& cube, const VelocityGrid& grid,
                              const SearchParams& params, ProgressSink& progress, CancelToken& cancel) {
  const MethodChoice choice = resolveMethod(backend, cube, grid, params.method);
  return searchWithChoice(backend, cube, grid, params, choice, progress, cancel);
}

}  // namespace st::search

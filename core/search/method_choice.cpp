#include "st/search/method_choice.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iterator>
#include <limits>

#include "st/common/error.hpp"
#include "st/common/parallel.hpp"
#include "st/search/statistic_noise.hpp"
#include "st/search/tree_plan.hpp"
#include "st/search/tree_polish.hpp"
#include "st/search/tree_search.hpp"
#include "st/search/velocity_grid.hpp"

namespace st::search {

namespace {

/// A statistic's noise above this many times the unit is a warning (statistic_noise.hpp): the Lowell frames'
/// 1.06 is a note, a spread of 1.2 makes a threshold of 7 one of 5.8 sigma.
constexpr double kNoiseWarningScale = 1.2;

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
// The device tree's tiles are 128-512 rows on the paper's problem (tree_device_plan.cpp): priced at 128,
// where the paper's problem has 1.15e10 additions (1.13e10 at 256; 1.22e10 in the fit above).
constexpr int kCudaTreePricedTileRows = 128;

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
  char text[400];
  std::snprintf(text, sizeof text, "auto: %s (estimated exact %s, tree %s; %.0fx fewer additions)", verdict,
                formatSeconds(e.exactSeconds).c_str(), formatSeconds(e.treeSeconds).c_str(),
                e.treeAdditions > 0.0 ? e.exactAdditions / e.treeAdditions : 0.0);
  return text;
}

}  // namespace

double treeSnrLoss(double fwhmPx) {
  if (!(fwhmPx > 0.0)) return std::numeric_limits<double>::quiet_NaN();
  // FWHM px, the worst of 12 objects (tests/core/test_tree_snr_loss_slow.cpp, 2026-11-25; medians 2.0, 1.2,
  // 0.8, 0.4%). Below 1.5 px the first segment's slope is extrapolated (a single-pixel source lost 41% in
  // the GPU benchmark of 2026-11-22).
  static constexpr double kTable[][2] = {{1.5, 0.030}, {2.0, 0.022}, {2.5, 0.016}, {3.5, 0.010}};
  constexpr std::size_t n = std::size(kTable);
  if (fwhmPx <= kTable[0][0]) {
    const double slope = (kTable[0][1] - kTable[1][1]) / (kTable[1][0] - kTable[0][0]);
    return std::min(1.0, kTable[0][1] + slope * (kTable[0][0] - fwhmPx));
  }
  for (std::size_t i = 1; i < n; ++i) {
    if (fwhmPx <= kTable[i][0]) {
      const double f = (fwhmPx - kTable[i - 1][0]) / (kTable[i][0] - kTable[i - 1][0]);
      return kTable[i - 1][1] + f * (kTable[i][1] - kTable[i - 1][1]);
    }
  }
  return kTable[n - 1][1];
}

void setPsf(MethodEstimate& e, double psfFwhmPx) {
  e.psfFwhmPx = psfFwhmPx > 0.0 ? psfFwhmPx : 0.0;
  e.treeSnrLoss = e.psfFwhmPx > 0.0 ? treeSnrLoss(e.psfFwhmPx) : 0.0;
}

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
  m.treeVelocityBlocks = false;
  m.treePricedTileRows = kCudaTreePricedTileRows;
  m.autoTreeMinSavingS = kCudaAutoTreeMinSavingS;
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
  e.autoTreeMinSavingS = model.autoTreeMinSavingS;
  e.exactSeconds = model.exactFixedS + e.exactAdditions / (model.exactAdditionsPerS * efficiency);
  e.treeSeconds = e.treeAdditions > 0.0
                      ? model.treeFixedS + model.treeOpsWeight * e.treeAdditions / model.exactAdditionsPerS
                      : std::numeric_limits<double>::infinity();
}

MethodEstimate estimateMethods(int width, int height, const std::vector<double>& dtS,
                               const VelocityGrid& grid, const MethodCostModel& model, unsigned threads,
                               std::size_t bufferBytes, const std::vector<PixelOffset>& offsets) {
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
  // The CPU tree searches the grid in the velocity blocks of fewest additions that fit (one tree when that
  // is cheapest, tree_search.hpp): priced as the blocks it will run.
  const std::size_t tileBudget = treeTileBudgetPerThread(threads, bufferBytes);
  const std::shared_ptr<const TreePlan> shared = sharedTreePlan(dtS, grid, offsets);
  const TreePlan& plan = *shared;
  TreeBlocks blocks{1, 1, grid.nvx, grid.nvy};
  if (model.treeVelocityBlocks) {
    blocks = treeVelocityBlocks(plan, width, height, treeBlockSplitBytes(bufferBytes), tileBudget);
  } else {
    blocks.tileRows = treeTileRows(plan, width, tileBudget);
    blocks.tileBytes = treeTileBytes(plan, width, blocks.tileRows);
    blocks.additions = treeAdditions(plan, width, height, blocks.tileRows);
  }
  e.treeBlocks = blocks.count();
  e.treeTileRows = blocks.tileRows;
  // The device's tiles are never taller than the image.
  e.treeAdditions = model.treePricedTileRows > 0
                        ? treeAdditions(plan, width, height, std::min(model.treePricedTileRows, height))
                        : blocks.additions;
  e.treeMaxShiftErrorPx = std::max(plan.maxAbsErrX, plan.maxAbsErrY);
  priceMethods(e, model);
  // Every thread holds one tile's partial stacks; there are no more busy threads than tiles.
  const std::size_t tiles = static_cast<std::size_t>((height + e.treeTileRows - 1) / e.treeTileRows);
  const std::size_t busy = std::min<std::size_t>(std::max(1u, threads), tiles);
  e.treeTileBytes = blocks.tileBytes;
  e.treeBusyThreads = static_cast<unsigned>(busy);
  e.treeWorkingBytes =
      busy * e.treeTileBytes + 12 * grid.count() +
      static_cast<std::size_t>(width + height) * static_cast<std::size_t>(grid.nvx + grid.nvy) * 8;
  return e;
}

std::string longSearchWarning(const MethodEstimate& estimate, const MethodChoice& choice,
                              const VelocityGrid& grid, double thresholdS) {
  const double s = choice.method == SearchMethod::Tree ? estimate.treeSeconds : estimate.exactSeconds;
  if (!(s > thresholdS) || !std::isfinite(s)) return {};
  char when[64];
  if (s >= 5400.0)
    std::snprintf(when, sizeof when, "%.1f h", s / 3600.0);
  else
    std::snprintf(when, sizeof when, "%.0f min", s / 60.0);
  char buf[512];
  std::snprintf(
      buf, sizeof buf,
      "the %s search is estimated at %s here (%d x %d velocities, %.3g px/s apart): the velocities grow as "
      "the square of the largest rate searched, so a smaller one (--vmax-deg-day, --vmax-px-s) or a GPU "
      "(--backend cuda) shortens it; Ctrl-C cancels",
      std::string(choice.method.name()).c_str(), when, grid.nvx, grid.nvy, grid.stepPxS);
  return buf;
}

MethodChoice chooseMethod(SearchMethod requested, const MethodEstimate& estimate, bool treeSupported,
                          const std::string& backendName) {
  constexpr SearchMethod kExact = SearchMethod::Exact;
  constexpr SearchMethod kTree = SearchMethod::Tree;
  if (requested == kExact) return {kExact, "requested"};
  if (requested == kTree) {
    if (!treeSupported) {
      throw InputError("the tree search is not available on the backend '" + backendName +
                       "': use the CPU backend, or method exact or auto");
    }
    return {kTree, "requested"};
  }
  if (requested != SearchMethod::Auto) {
    throw InputError("unknown search method (expected auto, exact or tree)");
  }
  if (!treeSupported) return {kExact, "auto: exact, the backend '" + backendName + "' has no tree search"};
  const MethodEstimate& e = estimate;
  if (!std::isfinite(e.treeSeconds)) return {kExact, "auto: exact, no tree plan for these frames"};
  if (e.exactSeconds < kAutoTreeMinSpeedup * e.treeSeconds)
    return {kExact, autoReason("exact, the tree would not be clearly faster", e)};
  if (e.exactSeconds - e.treeSeconds < e.autoTreeMinSavingS)
    return {kExact, autoReason("exact, too small for the tree's SNR loss to pay", e)};
  if (e.psfFwhmPx > 0.0 && e.treeSnrLoss > kAutoTreeMaxSnrLoss) {
    char text[160];
    std::snprintf(text, sizeof text,
                  "exact, the tree would lose ~%.1f%% of the SNR at PSF FWHM %.2f px (> %.0f%%)",
                  100.0 * e.treeSnrLoss, e.psfFwhmPx, 100.0 * kAutoTreeMaxSnrLoss);
    return {kExact, autoReason(text, e)};
  }
  if (e.psfFwhmPx > 0.0) {
    char text[128];
    std::snprintf(text, sizeof text, "tree, clearly faster, SNR cost ~%.1f%% at PSF FWHM %.2f px",
                  100.0 * e.treeSnrLoss, e.psfFwhmPx);
    return {kTree, autoReason(text, e)};
  }
  return {kTree, autoReason("tree, clearly faster", e)};
}

MethodChoice resolveMethod(const SearchBackend& backend, const FilteredCube& cube, const VelocityGrid& grid,
                           SearchMethod requested, MethodEstimate* estimate) {
  MethodEstimate e;
  const bool treeSupported = backend.supports(SearchMethod::Tree);
  // Only Auto needs the estimate (a tree plan: milliseconds even for the paper problem).
  if (requested == SearchMethod::Auto && treeSupported) {
    e = estimateMethods(cube.frames.width(), cube.frames.height(), cube.frames.timeOffsetsS(), grid,
                        costModelFor(backend), workerCount(), 0, cube.frames.frameOffsets());
  }
  setPsf(e, cube.psfFwhmPx);
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
  if (choice.method == SearchMethod::Tree && !result.candidates.empty()) {
    // The tree's candidates on the exact statistic, each around its own cell (tree_polish.hpp).
    const std::string text = polishNote(polishTreeCandidates(cube, result, kPolishedTreeCandidates, cancel));
    result.backendNote = result.backendNote.empty() ? text : result.backendNote + "\n" + text;
  }
  // The statistic's spread on this cube at random cells (statistic_noise.hpp), in the note every front end
  // shows; a spread far above the unit is the user's to see (the SNRs overstate how unlikely the detections
  // are).
  const StatisticNoise noise = measureStatisticNoise(cube, grid, result.minFrames, cancel);
  result.statisticNoise = noise;
  const std::string noiseText = statisticNoiseNote(noise);
  result.backendNote = result.backendNote.empty() ? noiseText : result.backendNote + "\n" + noiseText;
  if (noise.measured() && noise.scale > kNoiseWarningScale) {
    char text[240];
    std::snprintf(text, sizeof text,
                  "the search statistic's noise is %.2f x the unit sigma_F sqrt(N_in) on this cube: its SNRs "
                  "overstate significance, and Prob_false understates the false alarms; check the flat "
                  "field and the background",
                  noise.scale);
    result.warnings.push_back(text);
  }
  if (choice.method == SearchMethod::Tree && cube.psfFwhmPx > 0.0) {
    // What the tree costs for this cube (issue 16), in the note every front end shows.
    char text[200];
    std::snprintf(text, sizeof text,
                  "tree search: SNR cost against the exact search up to ~%.1f%% (worst on filtered point "
                  "sources at PSF FWHM %.2f px)",
                  100.0 * treeSnrLoss(cube.psfFwhmPx), cube.psfFwhmPx);
    result.backendNote = result.backendNote.empty() ? std::string(text) : result.backendNote + "\n" + text;
  }
  return result;
}

SearchResult searchWithMethod(SearchBackend& backend, const FilteredCube& cube, const VelocityGrid& grid,
                              const SearchParams& params, ProgressSink& progress, CancelToken& cancel) {
  const MethodChoice choice = resolveMethod(backend, cube, grid, params.method);
  return searchWithChoice(backend, cube, grid, params, choice, progress, cancel);
}

}  // namespace st::search

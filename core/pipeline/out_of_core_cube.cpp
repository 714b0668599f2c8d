#include "st/pipeline/out_of_core_cube.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>

#include "st/common/error.hpp"
#include "st/common/parallel.hpp"
#include "st/search/method_choice.hpp"
#include "st/search/tiled_search.hpp"
#include "st/stack/ipsa.hpp"
#include "st/stack/matched_filter.hpp"

namespace st::pipeline {

MemoryEstimate estimateOpenPeak(const CubeShape& shape, bool prepared, bool zeroBiased) {
  MemoryEstimate e;
  e.add("cube and mask", 5.0 * shape.samples());
  if (prepared) {
    e.add("matched-filtered cube", 5.0 * shape.samples());
    if (zeroBiased) e.add("unfiltered frames for the fits", 4.0 * shape.samples());
  }
  e.add("per-pixel images", kPreprocessImageBytesPerPixel * shape.width * shape.height);
  e.add("base", kBaseBytes);
  return e;
}

OpenPlan planOpen(const std::vector<std::string>& inputs, const io::LoadOptions& load,
                  std::size_t budgetBytes, unsigned threads, CancelToken& cancel) {
  OpenPlan plan;
  const io::InputSummary summary = io::summarizeInputs(inputs, load);
  plan.shape = {summary.width, summary.height, summary.frames};
  const double budget = static_cast<double>(budgetBytes);
  plan.need = estimateOpenPeak(plan.shape, true, true);
  if (plan.need.total() <= budget) return plan;  // whatever it is, it fits
  io::LoadOptions corner = load;
  const int bx = load.crop ? load.crop->x0 : 0, by = load.crop ? load.crop->y0 : 0;
  corner.crop = io::CropRegion{bx, by, std::min(plan.shape.width, 16), std::min(plan.shape.height, 16)};
  NullProgress quiet;
  const FrameCube c = io::loadFrames(inputs, corner, quiet, cancel);
  const std::string size = std::to_string(plan.shape.frames) + " frames of " +
                           std::to_string(plan.shape.width) + " x " + std::to_string(plan.shape.height) +
                           " px";
  const std::string over = ", over the memory budget of " + formatBytes(budget);
  if (const auto header = recognisePreparedHeader(c.header, cubeSource(c))) {
    plan.prepared = true;
    plan.need = estimateOpenPeak(plan.shape, true, header->state == PreparedState::ZeroBiased);
    if (plan.need.total() <= budget) return plan;
    plan.mode = OpenMode::OutOfCore;
    plan.reason = "the pre-processed cube's " + size + " need " + plan.need.describe() + " in memory" + over;
    return plan;
  }
  plan.need = estimatePreprocessPeak(plan.shape, true, std::max(1u, threads));
  if (plan.need.total() <= budget) return plan;
  plan.mode = OpenMode::Refused;
  plan.reason =
      size + " of raw frames need " + formatBytes(plan.need.total()) + " to pre-process in memory" + over +
      ". Pre-process them out of core first: `synthtrack-cli search FILES... --keep-scratch --scratch "
      "DIR/` (add --bias/--flat/--dark as needed) pre-processes them in strips of rows under its "
      "--memory-limit and keeps the filtered cube in DIR; open that cube here (a pre-processed cube "
      "over the budget opens out of core)";
  return plan;
}

FrameCube loadOutOfCoreRegion(const OutOfCoreCube& cube, const search::TileRect& r, CancelToken& cancel) {
  io::LoadOptions lo = cube.load;
  const int bx = lo.crop ? lo.crop->x0 : 0, by = lo.crop ? lo.crop->y0 : 0;
  lo.crop = io::CropRegion{bx + r.x0, by + r.y0, r.width, r.height};
  NullProgress quiet;
  return io::loadFrames(cube.inputs, lo, quiet, cancel);
}

OutOfCoreCube openOutOfCore(const std::vector<std::string>& inputs, const io::LoadOptions& load,
                            ProgressSink& progress, CancelToken& cancel) {
  OutOfCoreCube c;
  c.inputs = inputs;
  c.load = load;
  progress.report(0.0, "reading the headers");
  const io::InputSummary summary = io::summarizeInputs(inputs, load);
  c.shape = {summary.width, summary.height, summary.frames};
  FrameCube corner =
      loadOutOfCoreRegion(c, {0, 0, std::min(c.shape.width, 16), std::min(c.shape.height, 16)}, cancel);
  const std::string source = cubeSource(corner);
  c.header = readPreparedHeader(corner.header, source);
  c.meta.skyRate = c.header.skyRate;
  if (!c.header.psf) throw InputError(source + ": no PSFFWHM in the header (the matched filter's PSF)");
  c.meta.psfFwhmPx = c.header.psf->fwhm();
  if (c.header.state == PreparedState::ZeroBiased)
    c.filterHalfSize = stack::makeFilterKernel(*c.header.psf).halfSize;
  if (c.header.state == PreparedState::Filtered && c.header.sigmaF) {
    c.meta.sigmaF = *c.header.sigmaF;
  } else {
    progress.report(0.5, "measuring sigma_F on a central region");
    const int w = std::min(c.shape.width, 256), h = std::min(c.shape.height, 256);
    NullProgress quiet;
    PreparedSearchInput p = searchInputFromPrepared(
        loadOutOfCoreRegion(c, {(c.shape.width - w) / 2, (c.shape.height - h) / 2, w, h}, cancel), {}, quiet,
        cancel);
    c.meta.sigmaF = p.cube.sigmaF;
    c.notes.push_back("out of core: sigma_F " + std::to_string(p.cube.sigmaF) + " measured on the central " +
                      std::to_string(w) + " x " + std::to_string(h) + " px");
  }
  c.meta.frames = std::move(corner);
  progress.report(1.0, "opened out of core");
  return c;
}

Image stackOutOfCore(const OutOfCoreCube& cube, Velocity v, std::size_t budgetBytes, ProgressSink& progress,
                     CancelToken& cancel) {
  const int width = cube.shape.width, height = cube.shape.height;
  const auto shifts = stack::ipsaShifts(cube.meta.frames.timeOffsetsS(), v, cube.meta.frames.frameOffsets());
  int overlap = 0;
  for (const auto& s : shifts)
    overlap = std::max(overlap, std::abs(s.dy));
  // Rows a strip may read: 5 bytes a sample (pixels and mask) in half the budget.
  const double rowBytes = 5.0 * width * static_cast<double>(cube.shape.frames);
  const int readRows = std::max(1, static_cast<int>(0.5 * static_cast<double>(budgetBytes) / rowBytes));
  const int owned = std::max(1, readRows - 2 * overlap);
  Image out(width, height, 0.0f);
  for (int y0 = 0; y0 < height; y0 += owned) {
    cancel.throwIfCancelled();
    const int y1 = std::min(height, y0 + owned);
    const int r0 = std::max(0, y0 - overlap), r1 = std::min(height, y1 + overlap);
    const FrameCube strip = loadOutOfCoreRegion(cube, {0, r0, width, r1 - r0}, cancel);
    const stack::StackResult s = stack::stackIpsa(strip, v);
    for (int y = y0; y < y1; ++y)
      std::copy_n(s.sum.data() + static_cast<std::size_t>(y - r0) * width, width,
                  out.data() + static_cast<std::size_t>(y) * width);
    progress.report(static_cast<double>(y1) / height, "stacking out of core");
  }
  return out;
}

OutOfCoreSearch searchOutOfCore(const OutOfCoreCube& cube, const search::VelocityGrid& grid,
                                search::SearchParams params, std::size_t budgetBytes, ProgressSink& progress,
                                CancelToken& cancel) {
  const unsigned threads = workerCount();
  params.bufferBytes = searchBufferBytes(budgetBytes);
  const auto dt = cube.meta.frames.timeOffsetsS();
  search::MethodEstimate e =
      search::estimateMethods(cube.shape.width, cube.shape.height, dt, grid, search::cpuCostModel(threads),
                              threads, params.bufferBytes, cube.meta.frames.frameOffsets());
  search::setPsf(e, cube.meta.psfFwhmPx);
  search::MethodChoice method = search::chooseMethod(params.method, e, true, "cpu");
  const int overlap = search::searchOverlapPx(grid, dt) + cube.filterHalfSize;
  TiledSearchPlan plan = planTiledSearch(cube.shape, overlap, budgetBytes, e, method.method, threads);
  if (plan.tiles.empty() && method.method == search::SearchMethod::Tree &&
      params.method == search::SearchMethod::Auto) {
    plan = planTiledSearch(cube.shape, overlap, budgetBytes, e, search::SearchMethod::Exact, threads);
    if (!plan.tiles.empty())
      method = {search::SearchMethod::Exact,
                "auto: exact (the tree search's buffers do not fit the memory budget beside a tile)"};
  }
  if (plan.tiles.empty()) {
    MemoryBudget budget{budgetBytes, "the memory limit"};
    throw InputError(overBudgetMessage("searching " + std::to_string(cube.shape.frames) +
                                           " frames out of core (the smallest tile, " +
                                           std::to_string(8 + 2 * overlap) + " x " +
                                           std::to_string(8 + 2 * overlap) + " px with the overlap)",
                                       plan.smallestTile, budget));
  }
  params.method = method.method;
  params.treeThreads = plan.treeThreads;  // the tree's threads whose buffers fit beside a tile
  const double sigmaF = cube.meta.sigmaF;
  const search::TileLoader load = [&](const search::TileRect& t) {
    NullProgress quiet;
    PreparedSearchInput p =
        searchInputFromPrepared(loadOutOfCoreRegion(cube, t, cancel), {std::nullopt, sigmaF}, quiet, cancel);
    return std::move(p.cube);
  };
  OutOfCoreSearch out;
  // The tree's candidates re-scored by the exact statistic after it (as searchWithChoice does in memory):
  // the tiles that own them read again, the last tenth of the progress.
  const bool tree = params.method == search::SearchMethod::Tree;
  SubProgress searching(progress, 0.0, tree ? 0.9 : 1.0), rescoring(progress, 0.9, 1.0);
  out.result = search::searchTiled(load, plan.tiles, cube.shape.width, cube.shape.height, grid, params,
                                   searching, cancel);
  out.result.methodReason = method.reason;
  out.result.backendNote += ", " + std::to_string(overlap) + " px overlap";
  if (tree) (void)search::polishTiledTreeCandidates(load, plan.tiles, out.result, rescoring, cancel);
  out.tiles = plan.tiles.size();
  out.overlapPx = overlap;
  out.perTile = plan.perTile;
  return out;
}

}  // namespace st::pipeline

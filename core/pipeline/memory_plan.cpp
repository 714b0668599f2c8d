#include "st/pipeline/memory_plan.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "st/search/tree_search.hpp"

namespace st::pipeline {

namespace {

double searchWorking(const search::MethodEstimate& e, search::SearchMethod method) {
  return static_cast<double>(method == search::SearchMethod::Tree ? e.treeWorkingBytes : e.exactWorkingBytes);
}

}  // namespace

MemoryEstimate estimatePreprocessPeak(const CubeShape& s, bool keepZeroBiased, unsigned threads) {
  MemoryEstimate e;
  const double pixels = static_cast<double>(s.width) * s.height;
  e.add("cube", 4.0 * s.samples());
  e.add("pixel mask", 1.0 * s.samples());
  if (keepZeroBiased) e.add("filtered copy", 4.0 * s.samples());
  e.add("per-pixel images", kPreprocessImageBytesPerPixel * pixels);
  e.add("per-frame records", kPreprocessBytesPerFrame * static_cast<double>(s.frames));
  const double rowBuffers = static_cast<double>(std::min<std::size_t>(s.frames, 2000)) * s.width * 8.0 * 4.0;
  // Per thread: the per-pixel background's row buffers and kPreprocessThreadBytesPerPixel of frame-sized
  // buffers (a frame's FFT and SEP buffers, stack bands).
  e.add("per-thread buffers", std::max(1u, threads) * (rowBuffers + kPreprocessThreadBytesPerPixel * pixels));
  e.add("base", kBaseBytes);
  return e;
}

MemoryEstimate estimateSearchPeak(const CubeShape& s, const search::MethodEstimate& est,
                                  search::SearchMethod method) {
  MemoryEstimate e;
  e.add("filtered cube", 4.0 * s.samples());
  e.add("pixel mask", 1.0 * s.samples());
  e.add(method == search::SearchMethod::Tree ? "tree search buffers" : "exact search buffers", searchWorking(est, method));
  e.add("cells above threshold", kHitBytes * kExpectedHits);
  e.add("base", kBaseBytes);
  return e;
}

std::size_t searchBufferBytes(std::size_t budgetBytes) {
  return std::clamp(budgetBytes / 4, search::kTreeMinTileBudgetBytes, search::kTreeBuffersBytes);
}

TiledSearchPlan planTiledSearch(const CubeShape& s, int overlapPx, std::size_t budgetBytes,
                                const search::MethodEstimate& est, search::SearchMethod method,
                                unsigned threads) {
  TiledSearchPlan p;
  p.overlapPx = overlapPx;
  const double perPixel = 5.0 * static_cast<double>(s.frames);  // float + mask byte per frame
  const double others = kHitBytes * kExpectedHits + kBaseBytes;
  double working = searchWorking(est, method);
  if (method == search::SearchMethod::Tree && est.treeBusyThreads > 1 && est.treeTileBytes > 0) {
    // Every busy thread holds one tile of partial stacks: no more threads than half the room allows.
    const double stacks = static_cast<double>(est.treeTileBytes);
    const double shared = working - est.treeBusyThreads * stacks;  // the map and N_in ranges
    const double half = 0.5 * (static_cast<double>(budgetBytes) - others - shared);
    const auto fit = static_cast<unsigned>(std::clamp(std::floor(half / stacks), 1.0, double(est.treeBusyThreads)));
    p.treeThreads = fit;
    working = shared + fit * stacks;
  } else if (method == search::SearchMethod::Tree) {
    p.treeThreads = std::max(1u, est.treeBusyThreads);
  }
  const double fixed = working + others;
  // The loader's per-thread plane (float + flags) of a tile is at most one read row band of the tile: count
  // it as part of the tile (5 bytes x threads per pixel).
  const double perPixelAll = perPixel + 5.0 * std::max(1u, threads);
  const double room = static_cast<double>(budgetBytes) - fixed;
  const auto tileEstimate = [&](double readPixels) {
    MemoryEstimate e;
    e.add("tile of the filtered cube", 4.0 * s.frames * readPixels);
    e.add("tile pixel mask", 1.0 * s.frames * readPixels);
    e.add("loader plane buffers", 5.0 * std::max(1u, threads) * readPixels);
    e.add(method == search::SearchMethod::Tree
              ? "tree search buffers (" + std::to_string(p.treeThreads) + " threads)"
              : "exact search buffers",
          working);
    e.add("cells above threshold", kHitBytes * kExpectedHits);
    e.add("base", kBaseBytes);
    return e;
  };
  const double side = 8.0 + 2.0 * overlapPx;
  p.smallestTile = tileEstimate(side * side);
  if (room <= 0.0) return p;
  const auto maxRead = static_cast<std::size_t>(room / perPixelAll);
  p.tiles = search::planSearchTiles(s.width, s.height, overlapPx, maxRead);
  std::size_t largest = 0;
  for (const auto& t : p.tiles)
    largest = std::max(largest, t.read.pixels());
  p.perTile = tileEstimate(static_cast<double>(largest));
  return p;
}

std::string overBudgetMessage(const std::string& what, const MemoryEstimate& need, const MemoryBudget& budget) {
  std::ostringstream os;
  os << what << " needs " << need.describe() << ", more than the memory budget of "
     << formatBytes(static_cast<double>(budget.bytes)) << " (" << budget.source
     << "); give a larger --memory-limit, or fewer frames or a smaller region (--crop [x1:x2,y1:y2])";
  return os.str();
}

}  // namespace st::pipeline

#include "st/search/tree_polish.hpp"

#include <algorithm>
#include <cmath>
#include <set>
#include <tuple>

#include "st/common/parallel.hpp"
#include "st/search/ipsa.hpp"
#include "st/search/search_run.hpp"
#include "st/stats/false_alarm.hpp"

namespace st::search {
namespace {

constexpr int kHalfSteps = 2;  ///< grid steps searched on each side of the candidate's velocity
constexpr int kHalfPx = 1;     ///< pixels searched on each side of its position

}  // namespace

std::optional<Candidate> polishCandidate(const FilteredCube& cube, const SearchResult& result,
                                         const Candidate& c, int x0, int y0, CancelToken& cancel) {
  const VelocityGrid& grid = result.grid;
  const int w = cube.frames.width(), h = cube.frames.height();
  const int cx = c.x - x0, cy = c.y - y0;  // in the cube's pixels
  const std::vector<double> dt = cube.frames.timeOffsetsS();
  const int minFrames = std::max(1, result.minFrames);
  // Every cell by the reference sum at the search grid's own velocities (grid.at: the same doubles, so the
  // same whole-pixel shifts as the search), in the order y, x, ivy, ivx: of equal SNRs the first is kept.
  std::optional<Candidate> best;
  for (int y = std::max(0, cy - kHalfPx); y <= std::min(h - 1, cy + kHalfPx); ++y) {
    cancel.throwIfCancelled();
    for (int x = std::max(0, cx - kHalfPx); x <= std::min(w - 1, cx + kHalfPx); ++x)
      for (int ivy = std::max(0, c.ivy - kHalfSteps); ivy <= std::min(grid.nvy - 1, c.ivy + kHalfSteps);
           ++ivy)
        for (int ivx = std::max(0, c.ivx - kHalfSteps); ivx <= std::min(grid.nvx - 1, c.ivx + kHalfSteps);
             ++ivx) {
          const Velocity v = grid.at(ivx, ivy);
          const IpsaCell cell = ipsaReference(cube.frames, dt, x, y, v);
          if (cell.nIn < minFrames) continue;
          const double snr = cell.sum / (cube.sigmaF * std::sqrt(static_cast<double>(cell.nIn)));
          if (best && !(snr > best->snr)) continue;
          Candidate p = c;
          p.x = x + x0;
          p.y = y + y0;
          p.ivx = ivx;
          p.ivy = ivy;
          p.v = v;
          p.sum = cell.sum;
          p.nIn = cell.nIn;
          p.snr = snr;
          best = p;
        }
  }
  if (!best || !(best->snr > result.snrThreshold)) return std::nullopt;
  best->fap = stats::detectionFap(best->snr, result.trials.nx, result.trials.ny, result.trials.nvx,
                                  result.trials.nvy);
  return best;
}

PolishSummary finishPolish(SearchResult& result, const std::vector<std::optional<Candidate>>& polished,
                           double psfFwhmPx, const TrackFrames& frames, Velocity skyRate) {
  PolishSummary out;
  // Decreasing SNR, ties as setCandidates orders cells.
  const auto before = [](const Candidate& a, const Candidate& b) {
    if (a.snr != b.snr) return a.snr > b.snr;
    return std::tie(a.y, a.x, a.ivy, a.ivx) < std::tie(b.y, b.x, b.ivy, b.ivx);
  };
  using Cell = std::tuple<int, int, int, int>;
  const auto cellOf = [](const Candidate& c) { return Cell{c.x, c.y, c.ivx, c.ivy}; };
  // The re-scored candidates first (one per cell, the strongest), then the rest where their cell is free.
  std::vector<Candidate> rescored, rest;
  for (std::size_t i = 0; i < result.candidates.size(); ++i) {
    const Candidate& c = result.candidates[i];
    if (i >= polished.size()) {
      rest.push_back(c);
      continue;
    }
    ++out.rescored;
    if (!polished[i]) {
      ++out.dropped;
      continue;
    }
    if (cellOf(*polished[i]) != cellOf(c)) ++out.moved;
    rescored.push_back(*polished[i]);
  }
  std::stable_sort(rescored.begin(), rescored.end(), before);
  std::set<Cell> cells;
  result.candidates.clear();
  for (const auto* list : {&rescored, &rest})
    for (const Candidate& c : *list) {
      if (!cells.insert(cellOf(c)).second) {
        ++out.dropped;
        continue;
      }
      result.candidates.push_back(c);
    }
  std::stable_sort(result.candidates.begin(), result.candidates.end(), before);
  // A candidate re-scored onto the sky rate joins the static sources, once per cell and in their order.
  std::vector<Candidate> earlier = std::move(result.staticSources);
  result.staticSources.clear();
  setAsideStaticSources(result, psfFwhmPx, frames, skyRate);
  std::set<Cell> staticCells;
  for (const Candidate& c : result.staticSources)
    staticCells.insert(cellOf(c));
  for (const Candidate& c : earlier)
    if (staticCells.insert(cellOf(c)).second) result.staticSources.push_back(c);
  std::stable_sort(result.staticSources.begin(), result.staticSources.end(), before);
  return out;
}

PolishSummary polishTreeCandidates(const FilteredCube& cube, SearchResult& result, std::size_t maxCandidates,
                                   CancelToken& cancel) {
  std::vector<std::optional<Candidate>> polished(std::min(maxCandidates, result.candidates.size()));
  parallelFor(polished.size(), 1, [&](std::size_t i0, std::size_t i1) {
    for (std::size_t i = i0; i < i1; ++i)
      polished[i] = polishCandidate(cube, result, result.candidates[i], 0, 0, cancel);
  });
  const TrackFrames frames{cube.frames.timeOffsetsS(), cube.frames.width(), cube.frames.height(),
                           cube.frames.frameOffsets()};
  return finishPolish(result, polished, cube.psfFwhmPx, frames, cube.skyRate);
}

std::string polishNote(const PolishSummary& s) {
  return "tree candidates re-scored by the exact search within +-1 px and +-2 grid steps: " +
         std::to_string(s.moved) + " of " + std::to_string(s.rescored) + " moved to a better cell, " +
         std::to_string(s.dropped) + " dropped (below the threshold, or on a stronger one's cell)";
}

}  // namespace st::search

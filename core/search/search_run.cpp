#include "st/search/search_run.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <vector>

#include "st/common/error.hpp"
#include "st/common/parallel.hpp"
#include "st/search/ipsa.hpp"
#include "st/search/sidelobes.hpp"
#include "st/search/sky_motion.hpp"
#include "st/stats/false_alarm.hpp"

namespace st::search {

void validateSearchInput(const FilteredCube& cube, const VelocityGrid& grid, const SearchParams& params) {
  if (cube.frames.frameCount() < 2) {
    throw InputError("a velocity search needs at least 2 frames, got " +
                     std::to_string(cube.frames.frameCount()));
  }
  if (!(cube.frames.timeSpanS() > 0.0)) {
    throw InputError("the frames span no time (all mid-times equal): shifts cannot be computed");
  }
  if (!(cube.sigmaF > 0.0) || !std::isfinite(cube.sigmaF)) {
    throw InputError("sigma_F (noise of one filtered frame) must be positive and finite, got " +
                     std::to_string(cube.sigmaF));
  }
  if (grid.nvx <= 0 || grid.nvy <= 0) {
    throw InputError("the velocity grid is empty (" + std::to_string(grid.nvx) + " x " +
                     std::to_string(grid.nvy) + ")");
  }
  if (!(grid.stepPxS > 0.0) || !std::isfinite(grid.stepPxS)) {
    throw InputError("the velocity grid step must be positive, got " + std::to_string(grid.stepPxS) +
                     " px/s");
  }
  if (!(params.minFrameFraction >= 0.0 && params.minFrameFraction <= 1.0)) {
    throw InputError("the fraction of frames a track must cover must be in [0, 1], got " +
                     std::to_string(params.minFrameFraction));
  }
  if (params.maxCandidates < 1) throw InputError("the largest number of candidates must be at least 1");
  if (!params.targetFap && !std::isfinite(params.snrThreshold)) {
    throw InputError("the SNR threshold must be finite");
  }
}

double effectiveThreshold(const SearchParams& params, const TrialCounts& trials) {
  if (params.targetFap) return stats::snrThresholdForFap(*params.targetFap, trials.total());
  return params.snrThreshold;
}

int minFramesFor(const SearchParams& params, std::size_t frames) {
  const double need = std::ceil(params.minFrameFraction * static_cast<double>(frames) - 1e-9);
  return std::max(1, static_cast<int>(need));
}

int maxFramesInside(const std::vector<double>& timesS, int width, int height, Velocity v) {
  const int n = static_cast<int>(timesS.size());
  if (n == 0) return 0;
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const double tx = std::fabs(v.vx) > 0.0 ? width / std::fabs(v.vx) : kInf;
  const double ty = std::fabs(v.vy) > 0.0 ? height / std::fabs(v.vy) : kInf;
  const double window = std::min(tx, ty);
  std::vector<double> t = timesS;
  std::sort(t.begin(), t.end());
  if (!(window < t.back() - t.front())) return n;
  int best = 1;
  for (int a = 0, b = 0; a < n; ++a) {
    while (b < n && t[b] - t[a] <= window)
      ++b;
    best = std::max(best, b - a);
  }
  return best;
}

int minFramesFor(const SearchParams& params, const std::vector<double>& timesS, int width, int height,
                 const VelocityGrid& grid) {
  int fewest = static_cast<int>(timesS.size());
  for (const int ix : {0, grid.nvx - 1})
    for (const int iy : {0, grid.nvy - 1})
      fewest = std::min(fewest, maxFramesInside(timesS, width, height, grid.at(ix, iy)));
  return minFramesFor(params, static_cast<std::size_t>(std::max(fewest, 1)));
}

SearchResult startSearchResult(const FilteredCube& cube, const VelocityGrid& grid, const SearchParams& params,
                               std::string backend, SearchMethod method) {
  validateSearchInput(cube, grid, params);
  SearchResult result;
  result.grid = grid;
  result.trials = trialCounts(cube.frames.width(), cube.frames.height(), grid);
  result.snrThreshold = effectiveThreshold(params, result.trials);
  result.minFrames =
      minFramesFor(params, cube.frames.timeOffsetsS(), cube.frames.width(), cube.frames.height(), grid);
  result.tRefMjd = cube.frames.tRefMjd();
  result.backend = std::move(backend);
  result.method = method;
  return result;
}

void setCandidates(SearchResult& result, std::vector<CellHit> hits, const FilteredCube& cube,
                   const SearchParams& params) {
  setCandidates(result, std::move(hits), cube.psfFwhmPx, cube.frames.timeOffsetsS(), cube.frames.width(),
                cube.frames.height(), params, cube.frames.frameOffsets(), cube.skyRate);
}

void setCandidates(SearchResult& result, std::vector<CellHit> hits, double psfFwhmPx,
                   const std::vector<double>& dtS, int width, int height, const SearchParams& params,
                   const std::vector<PixelOffset>& offsets, Velocity skyRate) {
  // Total order (SNR descending, then y, x, ivy, ivx ascending): the cells kept at the cap and the
  // representative cell of a cluster do not depend on the order in which a backend found them.
  const auto before = [](const CellHit& a, const CellHit& b) {
    if (a.snr != b.snr) return a.snr > b.snr;
    if (a.y != b.y) return a.y < b.y;
    if (a.x != b.x) return a.x < b.x;
    if (a.ivy != b.ivy) return a.ivy < b.ivy;
    return a.ivx < b.ivx;
  };
  if (hits.size() > params.maxCandidates) {
    std::nth_element(hits.begin(), hits.begin() + static_cast<std::ptrdiff_t>(params.maxCandidates),
                     hits.end(), before);
    hits.resize(params.maxCandidates);
  }
  parallelSort(hits, before);
  result.staticSources.clear();
  result.candidates = clusterCells(hits, result.grid, defaultClusterParams(psfFwhmPx), result.trials);
  result.sidelobesMerged = static_cast<std::int64_t>(
      mergeSidelobes(result.candidates, dtS, width, height, psfFwhmPx, result.snrThreshold, offsets));
  setAsideStaticSources(result, psfFwhmPx, TrackFrames{dtS, width, height, offsets}, skyRate);
}

double trackSpanS(const Candidate& c, const TrackFrames& frames) {
  double lo = 0.0, hi = 0.0;
  bool any = false;
  for (std::size_t n = 0; n < frames.dtS.size(); ++n) {
    const double dt = frames.dtS[n];
    const PixelOffset o = frames.offsets.empty() ? PixelOffset{} : frames.offsets[n];
    const int sx = c.x + ipsaShift(c.v.vx, dt, o.x);
    const int sy = c.y + ipsaShift(c.v.vy, dt, o.y);
    if (sx < 0 || sy < 0 || sx >= frames.width || sy >= frames.height) continue;
    lo = any ? std::min(lo, dt) : dt;
    hi = any ? std::max(hi, dt) : dt;
    any = true;
  }
  return hi - lo;
}

void setAsideStaticSources(SearchResult& result, double psfFwhmPx, const TrackFrames& frames,
                           Velocity skyRate) {
  // Static sources: relative to the stars, less than one FWHM over the frames that hold the track (the
  // cell's velocity is the grid velocity, so the limit is compared with the offset of the grid cell from
  // the sky rate).
  double wholeSpan = 0.0;
  if (!frames.dtS.empty()) {
    const auto [lo, hi] = std::minmax_element(frames.dtS.begin(), frames.dtS.end());
    wholeSpan = *hi - *lo;
  }
  if (staticRateLimitPxS(psfFwhmPx, wholeSpan) <= 0.0) return;
  auto isStatic = [&](const Candidate& c) {
    const double own = trackSpanS(c, frames);
    const double limit = staticRateLimitPxS(psfFwhmPx, own > 0.0 ? own : wholeSpan);
    // Strictly less than the limit (a grid of FWHM / span steps keeps its first ring of cells as movers).
    return std::hypot(c.v.vx - skyRate.vx, c.v.vy - skyRate.vy) < limit * (1.0 - 1e-9);
  };
  // Each candidate judged once (its span is a pass over the frames), both lists kept in order.
  std::vector<Candidate> movers;
  for (Candidate& c : result.candidates)
    (isStatic(c) ? result.staticSources : movers).push_back(std::move(c));
  result.candidates = std::move(movers);
}

SearchResult runSearch(SearchBackend& backend, const FilteredCube& cube, const SearchRequest& request,
                       ProgressSink& progress, CancelToken& cancel) {
  const VelocityGrid grid = makeVelocityGrid(request.grid, cube);
  return backend.search(cube, grid, request.params, progress, cancel);
}

}  // namespace st::search

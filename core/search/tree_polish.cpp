#include "st/search/tree_polish.hpp"

#include <algorithm>
#include <cmath>
#include <set>
#include <tuple>

#include "ipsa_kernel.hpp"
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
  const int xa = std::max(0, cx - kHalfPx), xb = std::min(w - 1, cx + kHalfPx);
  const int ya = std::max(0, cy - kHalfPx), yb = std::min(h - 1, cy + kHalfPx);
  if (xa > xb || ya > yb) return std::nullopt;
  detail::KernelParams kp;
  kp.sigmaF = cube.sigmaF;
  kp.snrThreshold = result.snrThreshold;
  kp.minFrames = std::max(1, result.minFrames);
  kp.maxHits = 1;
  NullProgress quiet;
  const VelocityGrid local{c.v, grid.stepPxS, 2 * kHalfSteps + 1, 2 * kHalfSteps + 1};
  const detail::KernelOutput k = detail::runIpsaKernel(
      cube.frames, local, detail::Roi{xa, ya, xb - xa + 1, yb - ya + 1}, kp, quiet, cancel);
  int best = -1;
  for (int iv = 0; iv < static_cast<int>(local.count()); ++iv) {
    const int ivx = c.ivx + iv % local.nvx - kHalfSteps, ivy = c.ivy + iv / local.nvx - kHalfSteps;
    if (ivx < 0 || ivy < 0 || ivx >= grid.nvx || ivy >= grid.nvy) continue;  // not a cell of the search
    if (k.map.argX[iv] < 0) continue;
    if (best < 0 || k.map.maxSnr[iv] > k.map.maxSnr[best]) best = iv;
  }
  if (best < 0 || !(k.map.maxSnr[best] > result.snrThreshold)) return std::nullopt;
  Candidate p = c;
  p.ivx = c.ivx + best % local.nvx - kHalfSteps;
  p.ivy = c.ivy + best / local.nvx - kHalfSteps;
  p.v = grid.at(p.ivx, p.ivy);
  const IpsaCell cell =
      ipsaReference(cube.frames, cube.frames.timeOffsetsS(), k.map.argX[best], k.map.argY[best], p.v);
  p.x = k.map.argX[best] + x0;
  p.y = k.map.argY[best] + y0;
  p.sum = cell.sum;
  p.nIn = cell.nIn;
  p.snr = k.map.maxSnr[best];
  p.fap =
      stats::detectionFap(p.snr, result.trials.nx, result.trials.ny, result.trials.nvx, result.trials.nvy);
  return p;
}

PolishSummary finishPolish(SearchResult& result, const std::vector<std::optional<Candidate>>& polished,
                           double psfFwhmPx, const std::vector<double>& dtS, Velocity skyRate) {
  PolishSummary out;
  std::vector<Candidate> kept;
  for (std::size_t i = 0; i < result.candidates.size(); ++i) {
    const Candidate& c = result.candidates[i];
    if (i >= polished.size()) {
      kept.push_back(c);
      continue;
    }
    ++out.rescored;
    if (!polished[i]) {
      ++out.dropped;
      continue;
    }
    const Candidate& p = *polished[i];
    if (p.x != c.x || p.y != c.y || p.ivx != c.ivx || p.ivy != c.ivy) ++out.moved;
    kept.push_back(p);
  }
  // Decreasing SNR (ties as setCandidates orders cells), then one candidate per cell.
  std::stable_sort(kept.begin(), kept.end(), [](const Candidate& a, const Candidate& b) {
    if (a.snr != b.snr) return a.snr > b.snr;
    return std::tie(a.y, a.x, a.ivy, a.ivx) < std::tie(b.y, b.x, b.ivy, b.ivx);
  });
  std::set<std::tuple<int, int, int, int>> cells;
  result.candidates.clear();
  for (const Candidate& c : kept) {
    if (!cells.insert({c.x, c.y, c.ivx, c.ivy}).second) {
      ++out.dropped;
      continue;
    }
    result.candidates.push_back(c);
  }
  setAsideStaticSources(result, psfFwhmPx, dtS, skyRate);
  return out;
}

PolishSummary polishTreeCandidates(const FilteredCube& cube, SearchResult& result, std::size_t maxCandidates,
                                   CancelToken& cancel) {
  std::vector<std::optional<Candidate>> polished(std::min(maxCandidates, result.candidates.size()));
  for (std::size_t i = 0; i < polished.size(); ++i) {
    cancel.throwIfCancelled();
    polished[i] = polishCandidate(cube, result, result.candidates[i], 0, 0, cancel);
  }
  return finishPolish(result, polished, cube.psfFwhmPx, cube.frames.timeOffsetsS(), cube.skyRate);
}

std::string polishNote(const PolishSummary& s) {
  return "tree candidates re-scored by the exact search within +-1 px and +-2 grid steps: " +
         std::to_string(s.moved) + " of " + std::to_string(s.rescored) + " moved to a better cell, " +
         std::to_string(s.dropped) + " dropped (below the threshold, or on a stronger one's cell)";
}

}  // namespace st::search

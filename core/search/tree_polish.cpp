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

PolishSummary polishTreeCandidates(const FilteredCube& cube, SearchResult& result, std::size_t maxCandidates,
                                   CancelToken& cancel) {
  PolishSummary out;
  const VelocityGrid& grid = result.grid;
  const int w = cube.frames.width(), h = cube.frames.height();
  const std::vector<double> dt = cube.frames.timeOffsetsS();
  detail::KernelParams kp;
  kp.sigmaF = cube.sigmaF;
  kp.snrThreshold = result.snrThreshold;
  kp.minFrames = std::max(1, result.minFrames);
  kp.maxHits = 1;
  NullProgress quiet;
  const std::size_t n = std::min(maxCandidates, result.candidates.size());
  std::vector<char> keep(result.candidates.size(), 1);
  for (std::size_t i = 0; i < n; ++i) {
    cancel.throwIfCancelled();
    Candidate& c = result.candidates[i];
    const int x0 = std::max(0, c.x - kHalfPx), x1 = std::min(w - 1, c.x + kHalfPx);
    const int y0 = std::max(0, c.y - kHalfPx), y1 = std::min(h - 1, c.y + kHalfPx);
    const VelocityGrid local{c.v, grid.stepPxS, 2 * kHalfSteps + 1, 2 * kHalfSteps + 1};
    const detail::KernelOutput k = detail::runIpsaKernel(
        cube.frames, local, detail::Roi{x0, y0, x1 - x0 + 1, y1 - y0 + 1}, kp, quiet, cancel);
    ++out.rescored;
    int best = -1;
    for (int iv = 0; iv < static_cast<int>(local.count()); ++iv) {
      const int ivx = c.ivx + iv % local.nvx - kHalfSteps, ivy = c.ivy + iv / local.nvx - kHalfSteps;
      if (ivx < 0 || ivy < 0 || ivx >= grid.nvx || ivy >= grid.nvy) continue;  // not a cell of the search
      if (k.map.argX[iv] < 0) continue;
      if (best < 0 || k.map.maxSnr[iv] > k.map.maxSnr[best]) best = iv;
    }
    if (best < 0 || !(k.map.maxSnr[best] > result.snrThreshold)) {
      keep[i] = 0;
      ++out.dropped;
      continue;
    }
    Candidate p = c;
    p.ivx = c.ivx + best % local.nvx - kHalfSteps;
    p.ivy = c.ivy + best / local.nvx - kHalfSteps;
    p.v = grid.at(p.ivx, p.ivy);
    p.x = k.map.argX[best];
    p.y = k.map.argY[best];
    const IpsaCell cell = ipsaReference(cube.frames, dt, p.x, p.y, p.v);
    p.sum = cell.sum;
    p.nIn = cell.nIn;
    p.snr = k.map.maxSnr[best];
    p.fap =
        stats::detectionFap(p.snr, result.trials.nx, result.trials.ny, result.trials.nvx, result.trials.nvy);
    if (p.x != c.x || p.y != c.y || p.ivx != c.ivx || p.ivy != c.ivy) ++out.moved;
    c = p;
  }
  std::vector<Candidate> kept;
  for (std::size_t i = 0; i < result.candidates.size(); ++i)
    if (keep[i]) kept.push_back(result.candidates[i]);
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
  setAsideStaticSources(result, cube.psfFwhmPx, dt, cube.skyRate);
  return out;
}

}  // namespace st::search

#include "st/search/candidates.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <unordered_map>

#include "st/stats/false_alarm.hpp"

namespace st::search {

namespace {

class UnionFind {
 public:
  explicit UnionFind(std::size_t n) : m_parent(n) { std::iota(m_parent.begin(), m_parent.end(), 0); }
  std::size_t find(std::size_t i) {
    while (m_parent[i] != i) {
      m_parent[i] = m_parent[m_parent[i]];
      i = m_parent[i];
    }
    return i;
  }
  /// Makes the cluster of `child` part of the cluster of `root` (root must be a root).
  void attach(std::size_t child, std::size_t root) {
    child = find(child);
    if (child != root) m_parent[child] = root;
  }

 private:
  std::vector<std::size_t> m_parent;
};

/// Buckets in (x, y, ivx, ivy) with sides >= the linking radii: linked cells are in adjacent buckets.
std::uint64_t bucketKey(std::int64_t bx, std::int64_t by, std::int64_t bvx, std::int64_t bvy) {
  auto part = [](std::int64_t v) { return static_cast<std::uint64_t>(v) & 0xffffULL; };
  return part(bx) | part(by) << 16 | part(bvx) << 32 | part(bvy) << 48;
}

std::int64_t floorDiv(int v, std::int64_t side) {
  return v >= 0 ? v / side : -((-v + side - 1) / side);
}

}  // namespace

ClusterParams defaultClusterParams(double psfFwhmPx) {
  ClusterParams p;
  p.positionRadiusPx = std::max(2.0, 2.0 * psfFwhmPx);
  p.velocityRadiusSteps = 2;
  return p;
}

std::vector<Candidate> clusterCells(const std::vector<CellHit>& cellsIn, const VelocityGrid& grid,
                                    const ClusterParams& params, const TrialCounts& trials) {
  std::vector<CellHit> cells = cellsIn;
  const auto before = [](const CellHit& a, const CellHit& b) {
    if (a.snr != b.snr) return a.snr > b.snr;
    if (a.y != b.y) return a.y < b.y;
    return a.x < b.x;
  };
  // setCandidates hands them over sorted in a finer order already (130k cells of the paper's problem took
  // 5-10 ms to sort again).
  if (!std::is_sorted(cells.begin(), cells.end(), before))
    std::stable_sort(cells.begin(), cells.end(), before);
  const int radius = static_cast<int>(std::floor(params.positionRadiusPx));
  const int vRadius = params.velocityRadiusSteps;
  const std::int64_t side = std::max(1, radius);
  const std::int64_t vSide = std::max(1, vRadius);
  auto keyOf = [&](const CellHit& c, int dx, int dy, int dvx, int dvy) {
    return bucketKey(floorDiv(c.x, side) + dx, floorDiv(c.y, side) + dy, floorDiv(c.ivx, vSide) + dvx,
                     floorDiv(c.ivy, vSide) + dvy);
  };
  // Cells in one bucket are always within the linking radii of each other (sides <= radii), so the
  // union-find runs over buckets: a bucket joins a neighbouring one at the first linking pair. Dense
  // clusters (a bright source lights up ~1e6 cells) cost O(cells), not O(cells x neighbours).
  std::unordered_map<std::uint64_t, std::size_t> bucketIndex;
  std::vector<std::vector<std::size_t>> buckets;
  std::vector<std::size_t> bucketOf(cells.size());
  bucketIndex.reserve(cells.size());
  for (std::size_t i = 0; i < cells.size(); ++i) {
    const auto [it, added] = bucketIndex.try_emplace(keyOf(cells[i], 0, 0, 0, 0), buckets.size());
    if (added) buckets.emplace_back();
    buckets[it->second].push_back(i);
    bucketOf[i] = it->second;
  }
  auto links = [&](const CellHit& a, const CellHit& b) {
    return std::abs(a.x - b.x) <= radius && std::abs(a.y - b.y) <= radius &&
           std::abs(a.ivx - b.ivx) <= vRadius && std::abs(a.ivy - b.ivy) <= vRadius;
  };
  auto bucketsLink = [&](std::size_t ba, std::size_t bb) {
    for (const std::size_t i : buckets[ba])
      for (const std::size_t j : buckets[bb])
        if (links(cells[i], cells[j])) return true;
    return false;
  };
  // Buckets were created in increasing index of their first (best) cell, so bucket order is decreasing
  // peak SNR. Persistence merging over buckets (0-dimensional persistent homology): a bucket joins its best
  // linked neighbour's cluster; when it also links another cluster, the bucket's peak is the saddle between
  // the two, and the lower cluster is merged only when its peak rises less than the persistence above that
  // saddle (a noise bump on the ridge of one object), so distinct objects stay distinct candidates.
  auto peakOf = [&](std::size_t bucket) { return static_cast<double>(cells[buckets[bucket].front()].snr); };
  auto persistent = [&](double peak, double saddle) {
    return peak - saddle >= std::max(params.persistenceSnr, params.persistenceFraction * peak);
  };
  UnionFind uf(buckets.size());
  std::vector<std::size_t> roots;
  for (std::size_t b = 0; b < buckets.size(); ++b) {
    roots.clear();
    const CellHit& first = cells[buckets[b].front()];
    for (int d = 0; d < 81; ++d) {
      const auto it = bucketIndex.find(keyOf(first, d % 3 - 1, d / 3 % 3 - 1, d / 9 % 3 - 1, d / 27 - 1));
      if (it == bucketIndex.end() || it->second >= b) continue;
      const std::size_t root = uf.find(it->second);
      if (std::find(roots.begin(), roots.end(), root) != roots.end()) continue;
      if (bucketsLink(b, it->second)) roots.push_back(root);
    }
    if (roots.empty()) continue;  // a new peak
    const std::size_t best = *std::min_element(roots.begin(), roots.end());
    uf.attach(b, best);
    for (const std::size_t r : roots) {
      if (r != best && !persistent(peakOf(r), peakOf(b))) uf.attach(r, best);
    }
  }
  std::vector<Candidate> out;
  std::unordered_map<std::size_t, std::size_t> rootToCandidate;
  for (std::size_t i = 0; i < cells.size(); ++i) {
    const std::size_t root = uf.find(bucketOf[i]);
    const auto it = rootToCandidate.find(root);
    if (it != rootToCandidate.end()) {
      ++out[it->second].clusterCells;
      continue;
    }
    // Cells are in decreasing SNR and a root is its cluster's best bucket, so the first cell met is the peak.
    const CellHit& c = cells[i];
    Candidate cand;
    cand.x = c.x;
    cand.y = c.y;
    cand.ivx = c.ivx;
    cand.ivy = c.ivy;
    cand.v = grid.at(c.ivx, c.ivy);
    cand.sum = c.sum;
    cand.nIn = c.nIn;
    cand.snr = c.snr;
    cand.fap = stats::detectionFap(c.snr, trials.nx, trials.ny, trials.nvx, trials.nvy);
    cand.clusterCells = 1;
    rootToCandidate.emplace(root, out.size());
    out.push_back(cand);
  }
  return out;
}

}  // namespace st::search

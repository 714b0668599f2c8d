#include "st/search/tree_plan.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <memory>
#include <mutex>
#include <numeric>

#include "st/common/error.hpp"
#include "st/search/ipsa.hpp"

namespace st::search {

namespace {

/// Child velocities tried on either side of the nearest one.
constexpr int kTreeNeighbours = 2;

/// Axis velocities of a non-root node of time span `spanS`: centre + m * step, |m| <= K, step = max(grid
/// step, kTreeStepPx / span), K the fewest that leave every search-grid velocity within step / 2 of one.
std::vector<double> nodeAxis(double centre, double gridStep, int gridCount, double spanS) {
  const double halfRange = 0.5 * (gridCount - 1) * gridStep;
  const double step =
      spanS > 0.0 ? std::max(gridStep, kTreeStepPx / spanS) : std::numeric_limits<double>::max();
  const int k = step >= std::numeric_limits<double>::max() || halfRange <= 0.0
                    ? 0
                    : std::max(0, static_cast<int>(std::ceil(halfRange / step - 0.5 - 1e-9)));
  std::vector<double> v(static_cast<std::size_t>(2 * k + 1));
  for (int m = -k; m <= k; ++m)
    v[static_cast<std::size_t>(m + k)] = centre + m * (k == 0 ? 0.0 : step);
  return v;
}

int buildNodes(TreePlan& plan, int first, int last, int depth, const VelocityGrid& grid) {
  const int index = static_cast<int>(plan.nodes.size());
  plan.nodes.emplace_back();
  plan.depth = std::max(plan.depth, depth);
  {
    TreeNode& n = plan.nodes.back();
    n.first = first;
    n.last = last;
    n.depth = depth;
    n.spanS = plan.dt[last - 1] - plan.dt[first];
  }
  const double span = plan.nodes[index].spanS;
  if (last - first > 1 && span > 0.0) {
    const double mid = 0.5 * (plan.dt[first] + plan.dt[last - 1]);
    const int m = static_cast<int>(std::lower_bound(plan.dt.begin() + first, plan.dt.begin() + last, mid) -
                                   plan.dt.begin());
    const int l = buildNodes(plan, first, m, depth + 1, grid);
    const int r = buildNodes(plan, m, last, depth + 1, grid);
    plan.nodes[index].left = l;
    plan.nodes[index].right = r;
  }
  TreeNode& n = plan.nodes[index];
  if (index == 0) {
    for (int i = 0; i < grid.nvx; ++i)
      n.x.v.push_back(grid.at(i, 0).vx);
    for (int i = 0; i < grid.nvy; ++i)
      n.y.v.push_back(grid.at(0, i).vy);
  } else {
    n.x.v = nodeAxis(grid.centre.vx, grid.stepPxS, grid.nvx, span);
    n.y.v = nodeAxis(grid.centre.vy, grid.stepPxS, grid.nvy, span);
  }
  return index;
}

/// Best child velocity and offset for parent velocity v over the child's frames, and its deviation from the
/// target: round(v dt_k) - P_k at the root (what the result is judged by), the real line v dt_k - P_k below
/// it (a pattern close to its line composes best with the levels above).
struct Pick {
  TreeChoice choice;
  double maxErr = std::numeric_limits<double>::max();
  double sumErr = std::numeric_limits<double>::max();
};

Pick pickChild(const TreePlan& plan, const TreeNode& child, const TreeAxis& ca, const std::vector<int>& pre,
               double v, bool root, bool isX) {
  const int m = child.last - child.first;
  const int nv = static_cast<int>(ca.v.size());
  int nearest = 0;
  for (int j = 1; j < nv; ++j) {
    if (std::abs(ca.v[j] - v) < std::abs(ca.v[nearest] - v)) nearest = j;
  }
  std::vector<double> target(static_cast<std::size_t>(m));
  for (int k = 0; k < m; ++k) {
    const int f = child.first + k;
    const double o = isX ? plan.ox[f] : plan.oy[f];
    target[k] = (root ? ipsaShift(v, plan.dt[f], o) : o + v * plan.dt[f]) - pre[f];
  }
  Pick best;
  for (int j = std::max(0, nearest - kTreeNeighbours); j <= std::min(nv - 1, nearest + kTreeNeighbours);
       ++j) {
    const int* p = ca.pattern.data() + static_cast<std::size_t>(j) * m;
    double mn = std::numeric_limits<double>::max();
    double mx = std::numeric_limits<double>::lowest();
    for (int k = 0; k < m; ++k) {
      mn = std::min(mn, p[k] - target[k]);
      mx = std::max(mx, p[k] - target[k]);
    }
    const int aLow = -static_cast<int>(std::ceil(0.5 * (mx + mn)));
    for (int a = aLow; a <= aLow + 1; ++a) {
      const double maxErr = std::max(std::abs(a + mx), std::abs(a + mn));
      double sumErr = 0;
      for (int k = 0; k < m; ++k)
        sumErr += std::abs(a + p[k] - target[k]);
      if (maxErr < best.maxErr - 1e-9 || (maxErr < best.maxErr + 1e-9 && sumErr < best.sumErr)) {
        best = {{j, a}, maxErr, sumErr};
      }
    }
  }
  return best;
}

/// Fills node.axis choices and pattern from its children's (post-order); returns the root deviation.
int planAxis(TreePlan& plan, int index, bool isX) {
  const bool root = index == 0;
  TreeNode& n = plan.nodes[index];
  TreeAxis& a = isX ? n.x : n.y;
  const std::vector<int>& pre = isX ? plan.preX : plan.preY;
  const std::vector<double>& off = isX ? plan.ox : plan.oy;
  const int m = n.last - n.first;
  a.pattern.assign(a.v.size() * static_cast<std::size_t>(m), 0);
  if (n.leaf()) {
    for (std::size_t i = 0; i < a.v.size(); ++i) {
      for (int k = 0; k < m; ++k)
        a.pattern[i * m + k] = ipsaShift(a.v[i], plan.dt[n.first + k], off[n.first + k]) - pre[n.first + k];
    }
    return 0;
  }
  double worst = 0;
  for (const int c : {n.left, n.right})
    planAxis(plan, c, isX);
  const TreeNode& l = plan.nodes[n.left];
  const TreeNode& r = plan.nodes[n.right];
  const TreeAxis& la = isX ? l.x : l.y;
  const TreeAxis& ra = isX ? r.x : r.y;
  a.left.resize(a.v.size());
  a.right.resize(a.v.size());
  for (std::size_t i = 0; i < a.v.size(); ++i) {
    const Pick pl = pickChild(plan, l, la, pre, a.v[i], root, isX);
    const Pick pr = pickChild(plan, r, ra, pre, a.v[i], root, isX);
    a.left[i] = pl.choice;
    a.right[i] = pr.choice;
    worst = std::max({worst, pl.maxErr, pr.maxErr});
    const int ml = l.last - l.first;
    const int mr = r.last - r.first;
    for (int k = 0; k < ml; ++k)
      a.pattern[i * m + k] =
          pl.choice.offset + la.pattern[static_cast<std::size_t>(pl.choice.child) * ml + k];
    for (int k = 0; k < mr; ++k)
      a.pattern[i * m + ml + k] =
          pr.choice.offset + ra.pattern[static_cast<std::size_t>(pr.choice.child) * mr + k];
  }
  return static_cast<int>(std::lround(worst));
}

/// Margins: a child's stacks must cover every position its parent reads. Tracked per axis velocity along the
/// actual paths (reach[j] = the range of cumulative offsets of the root velocities that use velocity j), so
/// the margins stay near the grid's range times the node's distance from t_ref.
void planExtents(TreePlan& plan, int index, const std::vector<std::pair<int, int>>& reachX,
                 const std::vector<std::pair<int, int>>& reachY) {
  TreeNode& n = plan.nodes[index];
  for (const bool isX : {true, false}) {
    TreeAxis& a = isX ? n.x : n.y;
    const auto& reach = isX ? reachX : reachY;
    a.lo = std::numeric_limits<int>::max();
    a.hi = std::numeric_limits<int>::min();
    a.used.assign(reach.size(), 0);
    a.reachLo.assign(reach.size(), 0);
    a.reachHi.assign(reach.size(), 0);
    for (std::size_t j = 0; j < reach.size(); ++j) {
      const auto [lo, hi] = reach[j];
      if (lo > hi) continue;  // a velocity no root velocity uses: its stacks are not built
      a.used[j] = 1;
      a.reachLo[j] = lo;
      a.reachHi[j] = hi;
      a.lo = std::min(a.lo, lo);
      a.hi = std::max(a.hi, hi);
    }
    if (a.lo > a.hi) a.lo = a.hi = 0;
  }
  if (n.leaf()) return;
  for (const bool isLeft : {true, false}) {
    const int ci = isLeft ? n.left : n.right;
    std::vector<std::pair<int, int>> childReach[2];
    for (const bool isX : {true, false}) {
      const TreeAxis& pa = isX ? n.x : n.y;
      const auto& reach = isX ? reachX : reachY;
      const TreeAxis& ca = isX ? plan.nodes[ci].x : plan.nodes[ci].y;
      auto& out = childReach[isX ? 0 : 1];
      out.assign(ca.v.size(), {std::numeric_limits<int>::max(), std::numeric_limits<int>::min()});
      const auto& choices = isLeft ? pa.left : pa.right;
      for (std::size_t i = 0; i < choices.size(); ++i) {
        if (reach[i].first > reach[i].second) continue;
        auto& r = out[static_cast<std::size_t>(choices[i].child)];
        r.first = std::min(r.first, reach[i].first + choices[i].offset);
        r.second = std::max(r.second, reach[i].second + choices[i].offset);
      }
    }
    planExtents(plan, ci, childReach[0], childReach[1]);
  }
}

}  // namespace

TreePlan buildTreePlan(const std::vector<double>& dtS, const VelocityGrid& grid,
                       const std::vector<PixelOffset>& offsets) {
  if (dtS.size() < 2) throw InputError("the tree search needs at least 2 frames");
  if (!offsets.empty() && offsets.size() != dtS.size()) {
    throw InputError("the tree search got " + std::to_string(offsets.size()) + " frame offsets for " +
                     std::to_string(dtS.size()) + " frames");
  }
  if (grid.nvx <= 0 || grid.nvy <= 0 || !(grid.stepPxS > 0.0)) {
    throw InputError("the tree search needs a non-empty velocity grid with a positive step");
  }
  TreePlan plan;
  plan.frame.resize(dtS.size());
  std::iota(plan.frame.begin(), plan.frame.end(), std::size_t{0});
  std::stable_sort(plan.frame.begin(), plan.frame.end(),
                   [&](std::size_t a, std::size_t b) { return dtS[a] < dtS[b]; });
  for (const std::size_t f : plan.frame) {
    const PixelOffset o = offsets.empty() ? PixelOffset{} : offsets[f];
    plan.dt.push_back(dtS[f]);
    plan.ox.push_back(o.x);
    plan.oy.push_back(o.y);
    plan.preX.push_back(ipsaShift(grid.centre.vx, dtS[f], o.x));
    plan.preY.push_back(ipsaShift(grid.centre.vy, dtS[f], o.y));
  }
  if (!(plan.dt.back() > plan.dt.front())) throw InputError("the tree search needs a positive time span");
  buildNodes(plan, 0, static_cast<int>(dtS.size()), 0, grid);
  plan.maxAbsErrX = planAxis(plan, 0, true);
  plan.maxAbsErrY = planAxis(plan, 0, false);
  planExtents(plan, 0, std::vector<std::pair<int, int>>(static_cast<std::size_t>(grid.nvx), {0, 0}),
              std::vector<std::pair<int, int>>(static_cast<std::size_t>(grid.nvy), {0, 0}));
  return plan;
}

std::shared_ptr<const TreePlan> sharedTreePlan(const std::vector<double>& dtS, const VelocityGrid& grid,
                                               const std::vector<PixelOffset>& offsets) {
  if (!offsets.empty() && offsets.size() != dtS.size()) {
    return std::make_shared<const TreePlan>(buildTreePlan(dtS, grid, offsets));  // throws, naming the counts
  }
  struct Kept {
    std::vector<double> dt;
    std::vector<PixelOffset> offsets;  // empty when all are 0
    VelocityGrid grid;
    std::shared_ptr<const TreePlan> plan;
  };
  // Two plans, the last used first: a re-search on another grid (the GUI's) and a return to the first one
  // do not rebuild either. (The estimate and the search of one cube ask with the same offsets.)
  static std::mutex mutex;
  static Kept kept[2];
  const bool zero = std::all_of(offsets.begin(), offsets.end(),
                                [](const PixelOffset& o) { return o.x == 0.0 && o.y == 0.0; });
  const std::vector<PixelOffset> key = zero ? std::vector<PixelOffset>{} : offsets;
  auto same = [&](const Kept& k) {
    return k.plan && k.dt == dtS && k.grid.nvx == grid.nvx && k.grid.nvy == grid.nvy &&
           k.grid.stepPxS == grid.stepPxS && k.grid.centre.vx == grid.centre.vx &&
           k.grid.centre.vy == grid.centre.vy && k.offsets.size() == key.size() &&
           std::equal(k.offsets.begin(), k.offsets.end(), key.begin(),
                      [](const PixelOffset& p, const PixelOffset& q) { return p.x == q.x && p.y == q.y; });
  };
  {
    const std::lock_guard lock(mutex);
    for (int i = 0; i < 2; ++i) {
      if (!same(kept[i])) continue;
      if (i == 1) std::swap(kept[0], kept[1]);
      return kept[0].plan;
    }
  }
  auto plan = std::make_shared<const TreePlan>(buildTreePlan(dtS, grid, key));
  const std::lock_guard lock(mutex);
  kept[1] = std::move(kept[0]);
  kept[0] = {dtS, key, grid, plan};
  return plan;
}

namespace {

/// The kept velocities [lo, hi] of a node's axis: those on some root velocity's path (at least one: every
/// node is on a path).
std::pair<int, int> usedRange(const TreeAxis& a) {
  const auto first = std::find(a.used.begin(), a.used.end(), 1);
  if (first == a.used.end()) return {0, 0};
  const auto last = std::find(a.used.rbegin(), a.used.rend(), 1);
  return {static_cast<int>(first - a.used.begin()), static_cast<int>(a.used.rend() - last) - 1};
}

/// Keeps velocities `keep` = [lo, hi] of axis `a` (its velocity j is `from`'s base + j): values, used flags,
/// reaches, choices (child indices moved into the kept ranges `left` and `right` of the children) and the
/// shift pattern rows of `from` over m frames.
void trimAxis(TreeAxis& a, const TreeAxis& from, int base, std::pair<int, int> keep, int m,
              std::pair<int, int> left, std::pair<int, int> right) {
  const auto [lo, hi] = keep;
  const auto cut = [lo, hi](auto& v) {
    if (!v.empty()) v.assign(v.begin() + lo, v.begin() + hi + 1);
  };
  cut(a.v);
  cut(a.used);
  cut(a.reachLo);
  cut(a.reachHi);
  cut(a.left);
  cut(a.right);
  // A choice of an unused velocity may point outside the child's kept range: never read, clamped.
  for (auto [choices, range] : {std::pair{&a.left, left}, std::pair{&a.right, right}}) {
    for (TreeChoice& c : *choices)
      c.child = std::clamp(c.child - range.first, 0, range.second - range.first);
  }
  const auto rows = static_cast<std::size_t>(m);
  a.pattern.assign(from.pattern.begin() + static_cast<std::ptrdiff_t>((base + lo) * rows),
                   from.pattern.begin() + static_cast<std::ptrdiff_t>((base + hi + 1) * rows));
}

}  // namespace

TreePlan treeSubPlan(const TreePlan& whole, int ix0, int nx, int iy0, int ny) {
  if (whole.nodes.empty()) throw InputError("velocity block of an empty tree plan");
  const TreeNode& root = whole.nodes.front();
  const int gx = static_cast<int>(root.x.v.size()), gy = static_cast<int>(root.y.v.size());
  if (nx <= 0 || ny <= 0 || ix0 < 0 || iy0 < 0 || ix0 + nx > gx || iy0 + ny > gy) {
    throw InputError("velocity block " + std::to_string(nx) + " x " + std::to_string(ny) + " at (" +
                     std::to_string(ix0) + ", " + std::to_string(iy0) + ") outside the tree's " +
                     std::to_string(gx) + " x " + std::to_string(gy) + " grid");
  }
  TreePlan sub;
  sub.frame = whole.frame;
  sub.dt = whole.dt;
  sub.ox = whole.ox;
  sub.oy = whole.oy;
  sub.preX = whole.preX;
  sub.preY = whole.preY;
  sub.depth = whole.depth;
  sub.maxAbsErrX = whole.maxAbsErrX;
  sub.maxAbsErrY = whole.maxAbsErrY;
  // The nodes' velocities and choices (shifts later, only the kept rows), the root's cut to the block; then
  // the margins of the block's paths alone.
  sub.nodes.resize(whole.nodes.size());
  for (std::size_t i = 0; i < whole.nodes.size(); ++i) {
    const TreeNode& w = whole.nodes[i];
    TreeNode& n = sub.nodes[i];
    n.first = w.first;
    n.last = w.last;
    n.spanS = w.spanS;
    n.left = w.left;
    n.right = w.right;
    n.depth = w.depth;
    n.combined = !w.direct();
    for (const bool isX : {true, false}) {
      const TreeAxis& wa = isX ? w.x : w.y;
      TreeAxis& a = isX ? n.x : n.y;
      const int a0 = i == 0 ? (isX ? ix0 : iy0) : 0;
      const int an = i == 0 ? (isX ? nx : ny) : static_cast<int>(wa.v.size());
      a.v.assign(wa.v.begin() + a0, wa.v.begin() + a0 + an);
      if (!wa.left.empty()) {
        a.left.assign(wa.left.begin() + a0, wa.left.begin() + a0 + an);
        a.right.assign(wa.right.begin() + a0, wa.right.begin() + a0 + an);
      }
    }
  }
  planExtents(sub, 0, std::vector<std::pair<int, int>>(static_cast<std::size_t>(nx), {0, 0}),
              std::vector<std::pair<int, int>>(static_cast<std::size_t>(ny), {0, 0}));
  // Each node keeps its used range; a parent's choices move with its children's kept ranges.
  std::vector<std::pair<int, int>> keepX(sub.nodes.size()), keepY(sub.nodes.size());
  for (std::size_t i = 0; i < sub.nodes.size(); ++i) {
    keepX[i] = usedRange(sub.nodes[i].x);
    keepY[i] = usedRange(sub.nodes[i].y);
  }
  for (std::size_t i = 0; i < sub.nodes.size(); ++i) {
    TreeNode& n = sub.nodes[i];
    const TreeNode& w = whole.nodes[i];
    const int m = n.last - n.first;
    const auto child = [&](int c, const std::vector<std::pair<int, int>>& keep) {
      return c < 0 ? std::pair{0, 0} : keep[static_cast<std::size_t>(c)];
    };
    trimAxis(n.x, w.x, i == 0 ? ix0 : 0, keepX[i], m, child(n.left, keepX), child(n.right, keepX));
    trimAxis(n.y, w.y, i == 0 ? iy0 : 0, keepY[i], m, child(n.left, keepY), child(n.right, keepY));
  }
  return sub;
}

std::vector<std::pair<int, int>> treeImpliedShifts(const TreePlan& plan, int ix, int iy) {
  const TreeNode& root = plan.nodes.front();
  const std::size_t m = plan.frame.size();
  std::vector<std::pair<int, int>> out(m);
  for (std::size_t k = 0; k < m; ++k) {
    out[plan.frame[k]] = {root.x.pattern[static_cast<std::size_t>(ix) * m + k] + plan.preX[k],
                          root.y.pattern[static_cast<std::size_t>(iy) * m + k] + plan.preY[k]};
  }
  return out;
}

namespace {

double nodeAdditions(const TreePlan& plan, int index, int width, int tileRows) {
  const TreeNode& n = plan.nodes[static_cast<std::size_t>(index)];
  const double w = width + n.x.hi - n.x.lo;
  const double h = tileRows + n.y.hi - n.y.lo;
  if (n.direct()) return static_cast<double>(n.last - n.first) * w * h;  // each frame copied or added once
  double cols = 0.0, rows = 0.0;  // a stack is built only where its parents read it
  for (std::size_t j = 0; j < n.x.v.size(); ++j)
    cols += n.x.used[j] ? width + n.x.reachHi[j] - n.x.reachLo[j] : 0;
  for (std::size_t j = 0; j < n.y.v.size(); ++j)
    rows += n.y.used[j] ? tileRows + n.y.reachHi[j] - n.y.reachLo[j] : 0;
  return cols * rows + nodeAdditions(plan, n.left, width, tileRows) +
         nodeAdditions(plan, n.right, width, tileRows);
}

}  // namespace

double treeAdditions(const TreePlan& plan, int width, int height, int tileRows) {
  const int tiles = (height + tileRows - 1) / tileRows;
  return nodeAdditions(plan, 0, width, tileRows) * tiles;
}

namespace {

std::size_t nodeBytes(const TreeNode& n, int width, int tileRows) {
  return n.velocities() * static_cast<std::size_t>(width + n.x.hi - n.x.lo) *
         static_cast<std::size_t>(tileRows + n.y.hi - n.y.lo) * sizeof(float);
}

/// Peak bytes held while a node's stacks are built depth-first (its children's live until it is built).
std::size_t peakBytes(const TreePlan& plan, int index, int width, int tileRows) {
  const TreeNode& n = plan.nodes[static_cast<std::size_t>(index)];
  const std::size_t own = index == 0 ? 0 : nodeBytes(n, width, tileRows);
  if (n.direct() && index != 0) return own;
  const std::size_t l = nodeBytes(plan.nodes[static_cast<std::size_t>(n.left)], width, tileRows);
  const std::size_t r = nodeBytes(plan.nodes[static_cast<std::size_t>(n.right)], width, tileRows);
  return std::max(
      {peakBytes(plan, n.left, width, tileRows), l + peakBytes(plan, n.right, width, tileRows), l + r + own});
}

}  // namespace

std::size_t treeTileBytes(const TreePlan& plan, int width, int tileRows) {
  return peakBytes(plan, 0, width, tileRows);
}

}  // namespace st::search

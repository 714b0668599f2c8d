#include "tree_device_plan.hpp"

#include <algorithm>
#include <string>

#include "st/common/error.hpp"

namespace st::gpu {
namespace {

using search::TreeAxis;
using search::TreeNode;
using search::TreePlan;

/// Mosaic rows start on 128-byte boundaries (the root kernel reads aligned 32-float chunks).
int alignedPitch(int length) {
  return (length + 31) / 32 * 32;
}

/// Mosaic segments of one axis of one node: segment start per velocity (-1 when unused) and total length.
struct AxisLayout {
  std::vector<int> start;
  int length = 0;
};

AxisLayout layoutOf(const TreeAxis& a, int size) {
  AxisLayout l;
  l.start.assign(a.v.size(), -1);
  for (std::size_t j = 0; j < a.v.size(); ++j) {
    if (!a.used[j]) continue;
    l.start[j] = l.length;
    l.length += size + a.reachHi[j] - a.reachLo[j];
  }
  return l;
}

/// Per used velocity of a parent axis, the child's mosaic index of the parent's first position (the rest
/// follow contiguously), or -1 for an unused velocity. Checks that the parent reads inside the child's
/// stacks.
std::vector<int> childStarts(const TreeAxis& pa, const AxisLayout& pl,
                             const std::vector<search::TreeChoice>& choices, const TreeAxis& ca,
                             const AxisLayout& cl, int size) {
  std::vector<int> out(pa.v.size(), -1);
  for (std::size_t j = 0; j < pa.v.size(); ++j) {
    if (pl.start[j] < 0) continue;
    const search::TreeChoice ch = choices[j];
    const std::size_t cj = static_cast<std::size_t>(ch.child);
    const int lo = pa.reachLo[j] + ch.offset;
    const int hi = size + pa.reachHi[j] + ch.offset;
    if (cl.start[cj] < 0 || lo < ca.reachLo[cj] || hi > size + ca.reachHi[cj]) {
      throw GpuError("tree plan: a parent reads outside its child's stacks (velocity " + std::to_string(j) +
                     ")");
    }
    out[j] = cl.start[cj] + lo - ca.reachLo[cj];
  }
  return out;
}

/// Per mosaic index of a parent axis: the child's mosaic index.
void childIndices(const TreeAxis& pa, const AxisLayout& pl, const std::vector<search::TreeChoice>& choices,
                  const TreeAxis& ca, const AxisLayout& cl, int size, std::vector<int>& out) {
  const std::vector<int> starts = childStarts(pa, pl, choices, ca, cl, size);
  out.assign(static_cast<std::size_t>(pl.length), 0);
  for (std::size_t j = 0; j < pa.v.size(); ++j) {
    if (pl.start[j] < 0) continue;
    for (int i = 0; i < size + pa.reachHi[j] - pa.reachLo[j]; ++i)
      out[static_cast<std::size_t>(pl.start[j] + i)] = starts[j] + i;
  }
}

/// Direct node: per mosaic index, (velocity, position).
void directIndices(const TreeAxis& a, const AxisLayout& l, int size, std::vector<int2>& out) {
  for (std::size_t j = 0; j < a.v.size(); ++j) {
    if (l.start[j] < 0) continue;
    for (int q = a.reachLo[j]; q < size + a.reachHi[j]; ++q)
      out.push_back(int2{static_cast<int>(j), q});
  }
}

void appendPairs(const std::vector<int>& a, const std::vector<int>& b, std::vector<int2>& out) {
  for (std::size_t i = 0; i < a.size(); ++i)
    out.push_back(int2{a[i], b[i]});
}

void appendShifts(const TreeAxis& a, const std::vector<int>& pre, const TreeNode& n, std::vector<int>& out) {
  const int m = n.last - n.first;
  for (std::size_t j = 0; j < a.v.size(); ++j) {
    for (int k = 0; k < m; ++k)
      out.push_back(pre[static_cast<std::size_t>(n.first + k)] + a.pattern[j * m + k]);
  }
}

/// Depth of the shallowest direct node below the root reachable through non-direct nodes.
int shallowestDirect(const TreePlan& plan, int index) {
  const TreeNode& n = plan.nodes[static_cast<std::size_t>(index)];
  if (index != 0 && n.direct()) return n.depth;
  return std::min(shallowestDirect(plan, n.left), shallowestDirect(plan, n.right));
}

/// Nodes at depth `cut` in left-to-right order (the order of the tree's pairwise sums).
void cutNodes(const TreePlan& plan, int index, int cut, std::vector<int>& out) {
  const TreeNode& n = plan.nodes[static_cast<std::size_t>(index)];
  if (n.depth == cut) {
    out.push_back(index);
    return;
  }
  cutNodes(plan, n.left, cut, out);
  cutNodes(plan, n.right, cut, out);
}

}  // namespace

int treeCut(const TreePlan& plan, int wanted) {
  return std::max(1, std::min({wanted, kTreeMaxCut, shallowestDirect(plan, 0)}));
}

std::size_t TreeDevicePlan::tableBytes() const {
  return jobs.size() * sizeof(TreeJob) + (rowJobs.size() + rowTab.size()) * sizeof(int2) +
         segTab.size() * sizeof(int4) +
         (shiftX.size() + shiftY.size() + frameIndex.size() + cutPitch.size() + colBase.size() +
          rowBase.size()) *
             sizeof(int) +
         cutBase.size() * sizeof(long long);
}

TreeDevicePlan makeTreeDevicePlan(const TreePlan& plan, int width, int height, int tileRows, int cut) {
  TreeDevicePlan d;
  d.width = width;
  d.height = height;
  d.tileRows = tileRows;
  d.tiles = (height + tileRows - 1) / tileRows;
  d.cut = treeCut(plan, cut);
  d.nvx = static_cast<int>(plan.nodes[0].x.v.size());
  d.nvy = static_cast<int>(plan.nodes[0].y.v.size());
  for (const std::size_t f : plan.frame)
    d.frameIndex.push_back(static_cast<int>(f));

  const std::size_t count = plan.nodes.size();
  std::vector<AxisLayout> lx(count), ly(count);
  std::vector<char> active(count, 0);
  std::vector<long long> offset(count, 0);
  int maxDepth = d.cut;
  // Active: the cut nodes and, below them, every node under a non-direct active parent.
  for (std::size_t i = 0; i < count; ++i) {
    const TreeNode& n = plan.nodes[i];
    lx[i] = layoutOf(n.x, width);
    ly[i] = layoutOf(n.y, tileRows);
    if (n.depth == d.cut) active[i] = 1;
  }
  for (std::size_t i = 0; i < count; ++i) {  // parents precede children (pre-order)
    const TreeNode& n = plan.nodes[i];
    if (!active[i] || n.direct()) continue;
    active[static_cast<std::size_t>(n.left)] = active[static_cast<std::size_t>(n.right)] = 1;
    maxDepth = std::max(maxDepth, n.depth + 1);
  }
  std::vector<int> a, b;
  for (int depth = maxDepth; depth >= d.cut; --depth) {
    TreeDeviceLevel level;
    level.depth = depth;
    level.arena = depth & 1;
    level.jobBegin = static_cast<int>(d.jobs.size());
    level.rowBegin = static_cast<int>(d.rowJobs.size());
    long long used = 0;
    for (std::size_t i = 0; i < count; ++i) {
      const TreeNode& n = plan.nodes[i];
      if (!active[i] || n.depth != depth) continue;
      TreeJob j{};
      j.out = used;
      offset[i] = used;
      j.pitch = alignedPitch(lx[i].length);
      const int rows = ly[i].length;
      used += static_cast<long long>(j.pitch) * rows;
      j.segTable = static_cast<int>(d.segTab.size());
      j.rowTable = static_cast<int>(d.rowTab.size());
      j.direct = n.direct() ? 1 : 0;
      if (j.direct) {
        j.first = n.first;
        j.last = n.last;
        j.shiftX = static_cast<int>(d.shiftX.size());
        j.shiftY = static_cast<int>(d.shiftY.size());
        appendShifts(n.x, plan.preX, n, d.shiftX);
        appendShifts(n.y, plan.preY, n, d.shiftY);
        for (std::size_t jx = 0; jx < n.x.v.size(); ++jx) {
          if (lx[i].start[jx] >= 0)
            d.segTab.push_back(int4{lx[i].start[jx], width + n.x.reachHi[jx] - n.x.reachLo[jx],
                                    static_cast<int>(jx), n.x.reachLo[jx]});
        }
        directIndices(n.y, ly[i], tileRows, d.rowTab);
        d.additionsPerTile += static_cast<double>(j.pitch) * rows * (n.last - n.first);
      } else {
        const std::size_t l = static_cast<std::size_t>(n.left);
        const std::size_t r = static_cast<std::size_t>(n.right);
        j.left = offset[l];
        j.right = offset[r];
        j.leftPitch = alignedPitch(lx[l].length);
        j.rightPitch = alignedPitch(lx[r].length);
        const TreeNode& ln = plan.nodes[l];
        const TreeNode& rn = plan.nodes[r];
        a = childStarts(n.x, lx[i], n.x.left, ln.x, lx[l], width);
        b = childStarts(n.x, lx[i], n.x.right, rn.x, lx[r], width);
        for (std::size_t jx = 0; jx < n.x.v.size(); ++jx) {
          if (lx[i].start[jx] >= 0)
            d.segTab.push_back(
                int4{lx[i].start[jx], width + n.x.reachHi[jx] - n.x.reachLo[jx], a[jx], b[jx]});
        }
        childIndices(n.y, ly[i], n.y.left, ln.y, ly[l], tileRows, a);
        childIndices(n.y, ly[i], n.y.right, rn.y, ly[r], tileRows, b);
        appendPairs(a, b, d.rowTab);
        d.additionsPerTile += static_cast<double>(j.pitch) * rows;
      }
      const int jobIndex = static_cast<int>(d.jobs.size());
      for (int row = 0; row < rows; ++row)
        d.rowJobs.push_back(int2{jobIndex, row});
      j.segments = static_cast<int>(d.segTab.size()) - j.segTable;
      d.jobs.push_back(j);
    }
    level.jobEnd = static_cast<int>(d.jobs.size());
    level.rowEnd = static_cast<int>(d.rowJobs.size());
    // 64 floats of slack: the root kernel's chunk reads may pass the end of a mosaic by up to 31 floats.
    d.arenaFloats[level.arena] = std::max(d.arenaFloats[level.arena], static_cast<std::size_t>(used) + 64);
    d.levels.push_back(level);
  }

  // Root: for each cut node, the mosaic column (row) where each root vx (vy) reads image column (row) 0.
  std::vector<int> cuts;
  cutNodes(plan, 0, d.cut, cuts);
  for (std::size_t c = 0; c < cuts.size(); ++c) {
    const std::size_t ci = static_cast<std::size_t>(cuts[c]);
    d.cutBase.push_back(offset[ci]);
    d.cutPitch.push_back(alignedPitch(lx[ci].length));
  }
  for (const bool isX : {true, false}) {
    std::vector<int>& base = isX ? d.colBase : d.rowBase;
    const int nv = isX ? d.nvx : d.nvy;
    for (std::size_t c = 0; c < cuts.size(); ++c) {
      for (int iv = 0; iv < nv; ++iv) {
        int node = 0, j = iv, off = 0;
        for (int level = d.cut - 1; level >= 0; --level) {  // path bits, most significant first
          const TreeNode& n = plan.nodes[static_cast<std::size_t>(node)];
          const bool right = (c >> level) & 1u;
          const TreeAxis& ax = isX ? n.x : n.y;
          const search::TreeChoice ch = (right ? ax.right : ax.left)[static_cast<std::size_t>(j)];
          off += ch.offset;
          j = ch.child;
          node = right ? n.right : n.left;
        }
        const TreeNode& cn = plan.nodes[static_cast<std::size_t>(node)];
        const TreeAxis& ca = isX ? cn.x : cn.y;
        const AxisLayout& cl = isX ? lx[static_cast<std::size_t>(node)] : ly[static_cast<std::size_t>(node)];
        if (cl.start[static_cast<std::size_t>(j)] < 0)
          throw GpuError("tree plan: a root velocity uses an unused stack");
        base.push_back(cl.start[static_cast<std::size_t>(j)] + off - ca.reachLo[static_cast<std::size_t>(j)]);
      }
    }
  }
  d.additionsPerTile += static_cast<double>(width) * tileRows * d.nvx * d.nvy * ((1 << d.cut) - 1);
  return d;
}

}  // namespace st::gpu

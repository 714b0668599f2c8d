#pragma once
// The plan of the hierarchical ("tree") velocity search: a 2-D analogue of the Fast Dispersion Measure
// Transform (Zackay & Ofek 2017) for the IPSA statistic of ARCHITECTURE.md.
//
// Tree: the frames in time order are split recursively at the middle of each node's time span (not its frame
// count, so uneven cadences and gaps are handled) until a node holds one frame or frames of one mid-time.
// Each node keeps partial stacks only for the velocities distinguishable over its own span: per axis a
// regular grid centred on the search grid's centre with step max(grid step, kTreeStepPx / span), covering
// the search grid's range (the count per axis grows with the span, the number of 2-D stacks with its square).
// The root's grid is the search grid itself.
//
// Combination (per axis, x and y are independent because every grid is a product grid): a parent stack for
// axis velocity v is child(u) shifted by an integer offset a, for each of its two children. u is taken among
// the child's grid velocity nearest to v and its two neighbours, and a is chosen, so that the child's implied
// per-frame shifts plus a deviate least (max, then sum of |deviation|) from the exact shifts round(o_k + v dt_k)
// of ARCHITECTURE.md (o_k the frame's registration offset, usually 0). All shifts are "at t_ref": a node's stack at pixel q sums F_k(q + s_k) with s_k close to
// round(v dt_k), so no error accumulates from re-anchoring at node times; the deviation is measured and
// exposed (TreePlan::maxAbsErr*), and the tests check it is at most 1 px at every frame.
// Shifts are computed relative to the grid centre's own motion P_k = round(c dt_k), so the margins the
// partial stacks need are set by the grid's range, not by its centre (a sky rate).
#include <algorithm>
#include <cstddef>
#include <memory>
#include <utility>
#include <vector>

#include "st/search/types.hpp"

namespace st::search {

/// A node's velocity step is kTreeStepPx px of motion over the node's time span (at least the search grid's
/// step). 0.5 px: the velocity mismatch between a parent's velocity and its child's moves a sample by at most
/// 1/8 px at the child's ends. With 1 px (half the work at the top levels) up to ~44% of a velocity's frames
/// were 1 px off the exact track and an object near threshold lost ~15% of its SNR (paper cadence test).
inline constexpr double kTreeStepPx = 0.5;

/// Per parent axis velocity: which child axis velocity it uses and the integer offset (px) applied to it.
struct TreeChoice {
  int child = 0;
  int offset = 0;
};

/// One axis (x or y) of a node: its velocities and, for internal nodes, the choices into both children.
struct TreeAxis {
  std::vector<double> v;                ///< axis velocities, px/s (absolute, not relative to the centre)
  std::vector<TreeChoice> left, right;  ///< per velocity index; empty for a leaf
  std::vector<int> pattern;             ///< implied shifts minus P_k: [velocity][frame - node.first]
  std::vector<char> used;               ///< per velocity: some root velocity's path goes through it
  std::vector<int> reachLo, reachHi;  ///< per used velocity: its stack is needed at [reachLo, size + reachHi)
  int lo = 0;                         ///< stacks cover positions [lo, size + hi) (tile-relative)
  int hi = 0;
};

struct TreeNode {
  int first = 0;  ///< time-ordered frames [first, last)
  int last = 0;
  double spanS = 0.0;  ///< last minus first mid-time, seconds
  int left = -1;       ///< child node indices, -1 for a leaf
  int right = -1;
  int depth = 0;
  TreeAxis x, y;
  /// A velocity block's node left with one velocity of several (treeSubPlan): still built from its
  /// children, as the whole tree builds it, so that the block's sums are the whole tree's bit for bit.
  bool combined = false;
  [[nodiscard]] bool leaf() const noexcept { return left < 0; }
  /// Built directly from its frames (a leaf, or a node with one velocity: its subtree would add the same
  /// samples in about twice the work).
  [[nodiscard]] bool direct() const noexcept {
    return leaf() || (!combined && x.v.size() == 1 && y.v.size() == 1);
  }
  [[nodiscard]] std::size_t velocities() const noexcept { return x.v.size() * y.v.size(); }
  /// Velocities on some root velocity's path (only those stacks are built).
  [[nodiscard]] std::size_t usedVelocities() const noexcept {
    return static_cast<std::size_t>(std::count(x.used.begin(), x.used.end(), 1)) *
           static_cast<std::size_t>(std::count(y.used.begin(), y.used.end(), 1));
  }
};

struct TreePlan {
  std::vector<std::size_t> frame;  ///< cube frame index of the k-th frame in time order
  std::vector<double> dt;          ///< its t - t_ref, seconds
  std::vector<double> ox, oy;      ///< its registration offset o_k, px (0 unless registered)
  std::vector<int> preX, preY;     ///< P_k = round(o_k + centre dt_k) per axis
  std::vector<TreeNode> nodes;     ///< nodes[0] is the root; its axes are the search grid's
  int depth = 0;                   ///< deepest node level (root 0)
  int maxAbsErrX = 0;              ///< max over grid velocities and frames of |implied - round(v dt)|, px
  int maxAbsErrY = 0;
};

/// Builds the plan for frames with offsets `dtS` (t_n - t_ref, seconds, in cube order; at least 2 distinct
/// times) and `grid` (non-empty, positive step). Throws st::InputError otherwise. O(N_f x axis velocities).
/// `offsets` (cube order, FrameCube::frameOffsets(); empty = all 0) are the frames' registration offsets
/// o_k: the exact shifts the plan approximates are then round(o_k + v dt_k) (ARCHITECTURE.md).
TreePlan buildTreePlan(const std::vector<double>& dtS, const VelocityGrid& grid,
                       const std::vector<PixelOffset>& offsets = {});

/// buildTreePlan's plan, kept for the next call with the same frame times, offsets (empty and all-zero
/// alike) and grid, which gets the same plan: the method estimate and the search of one cube, and each
/// re-search, share one plan instead of building it each time (40-100 ms for 1500 frames and 297^2
/// velocities; issue 16). The last two plans are kept, process-wide (tens of MB for the paper's problem);
/// thread-safe.
std::shared_ptr<const TreePlan> sharedTreePlan(const std::vector<double>& dtS, const VelocityGrid& grid,
                                               const std::vector<PixelOffset>& offsets = {});

/// The plan of the block of root velocities [ix0, ix0 + nx) x [iy0, iy0 + ny) of `whole` (velocity blocks,
/// tree_search.hpp): the whole tree's node velocities, choices and shifts, each node keeping only the range
/// of its velocities on the block's paths, with margins for those alone. Its root velocity (jx, jy) is
/// `whole`'s (ix0 + jx, iy0 + jy), summed from the same samples in the same order as in the whole tree (the
/// same values, bit for bit, whatever the blocks). O(frames x axis velocities), no shift is re-planned.
/// Throws st::InputError for an empty block or one outside the grid.
TreePlan treeSubPlan(const TreePlan& whole, int ix0, int nx, int iy0, int ny);

/// The tree's implied integer shift (sx, sy) of every frame, in cube frame order, for grid velocity (ix, iy):
/// the root's stack at pixel (x, y) sums F_n(x + sx_n, y + sy_n) over frames with the sample inside.
std::vector<std::pair<int, int>> treeImpliedShifts(const TreePlan& plan, int ix, int iy);

/// Pixel additions (and copies) of a tree search over a width x height image in tiles of `tileRows` rows,
/// margins included: the operation count to compare with width x height x frames x velocities (exact).
double treeAdditions(const TreePlan& plan, int width, int height, int tileRows);

/// Peak bytes of partial stacks one tile of `tileRows` rows holds in the depth-first evaluation (a node's
/// children's stacks live until its own are built; the root's are never stored).
std::size_t treeTileBytes(const TreePlan& plan, int width, int tileRows);

}  // namespace st::search

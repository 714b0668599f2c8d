#include "st/search/tree_search.hpp"

#include <algorithm>
#include <atomic>
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#endif
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <mutex>
#include <tuple>

#include "ipsa_kernel.hpp"
#include "tree_region.hpp"
#include "st/common/error.hpp"
#include "st/common/parallel.hpp"
#include "st/search/candidates.hpp"
#include "st/search/ipsa.hpp"
#include "st/search/search_run.hpp"
#include "st/search/velocity_grid.hpp"

namespace st::search {

namespace {

/// [lo, hi): the time-ordered frames k with a <= s[k] < b, for a non-decreasing sequence s.
void validRange(const int* s, int n, int a, int b, int& lo, int& hi) {
  lo = static_cast<int>(std::lower_bound(s, s + n, a) - s);
  hi = std::max(lo, static_cast<int>(std::lower_bound(s, s + n, b) - s));
}

/// N_in ranges of one axis from the exact shifts: per axis velocity, per column (or row), the valid
/// time-ordered frame range, and the interior [a, b) where every frame is valid.
struct AxisRanges {
  int size = 0;
  std::vector<int> lo, hi;  ///< [velocity][position]
  std::vector<int> a, b;    ///< [velocity]
};

AxisRanges axisRanges(const std::vector<double>& axisV, const std::vector<double>& dt, int size) {
  const int n = static_cast<int>(dt.size());
  AxisRanges r;
  r.size = size;
  r.lo.resize(axisV.size() * size);
  r.hi.resize(axisV.size() * size);
  std::vector<int> s(static_cast<std::size_t>(n));
  for (std::size_t i = 0; i < axisV.size(); ++i) {
    // Non-decreasing in time order when v >= 0; for v < 0 mirror: count with -s and the mirrored window.
    const bool neg = axisV[i] < 0.0;
    for (int k = 0; k < n; ++k) {
      const int sh = std::clamp(ipsaShift(axisV[i], dt[k]), -size, size);
      s[neg ? n - 1 - k : k] = sh;
    }
    for (int p = 0; p < size; ++p) {
      int lo = 0, hi = 0;
      validRange(s.data(), n, -p, size - p, lo, hi);
      if (neg) std::tie(lo, hi) = std::pair{n - hi, n - lo};
      r.lo[i * size + p] = lo;
      r.hi[i * size + p] = hi;
    }
    const auto [mn, mx] = std::minmax_element(s.begin(), s.end());
    const int a = std::clamp(-*mn, 0, size);
    r.a.push_back(a);
    r.b.push_back(std::clamp(size - *mx, a, size));
  }
  return r;
}

/// Buffers reused across nodes and tiles (best fit), so stacks are neither zeroed nor page-faulted anew.
class BufferPool {
 public:
  std::vector<float> take(std::size_t n) {
    std::size_t best = m_free.size();
    for (std::size_t i = 0; i < m_free.size(); ++i) {
      if (m_free[i].size() >= n && (best == m_free.size() || m_free[i].size() < m_free[best].size()))
        best = i;
    }
    if (best == m_free.size()) return std::vector<float>(n);
    std::vector<float> v = std::move(m_free[best]);
    m_free.erase(m_free.begin() + static_cast<std::ptrdiff_t>(best));
    return v;
  }
  void give(std::vector<float>&& v) {
    if (!v.empty()) m_free.push_back(std::move(v));
  }

 private:
  std::vector<std::vector<float>> m_free;
};

struct Planes {
  std::vector<float> data;
  int pw = 0, ph = 0, nx = 0;
  [[nodiscard]] const float* plane(int jx, int jy) const {
    return data.data() + (static_cast<std::size_t>(jy) * nx + jx) * static_cast<std::size_t>(pw) * ph;
  }
};

/// One worker's share of the output: best cell per velocity and the cells above threshold.
struct WorkerState {
  std::vector<float> bestSnr;
  std::vector<int> bestX, bestY;
  std::vector<CellHit> hits;
  std::int64_t hitsTotal = 0;
  float floor = 0.0f;
  std::vector<float> row;
  std::vector<int> nIn, diff;  ///< registered frames: N_in of one row, and its scratch
  BufferPool pool;
};

struct Context {
  const FrameCube& cube;
  const TreePlan& plan;
  const SearchParams& params;
  int width = 0, height = 0, tileRows = 0;
  detail::Roi roi;  ///< output cells scanned (the owned part of an out-of-core tile; the image otherwise)
  float threshold = 0.0f;
  int minFrames = 1;
  std::size_t cap = 0;
  std::vector<float> invNorm;
  AxisRanges rx, ry;
  CancelToken& cancel;
  /// Registered frames (shifts not monotone in time): the exact shifts round(o_k + v dt_k), time order,
  /// [axis velocity][k], clamped to +-width/height, for N_in counted frame by frame.
  bool registered = false;
  std::vector<int> exactX, exactY;
};

std::vector<int> exactShifts(const std::vector<double>& axisV, const std::vector<double>& dt,
                             const std::vector<double>& off, int size) {
  std::vector<int> s(axisV.size() * dt.size());
  for (std::size_t i = 0; i < axisV.size(); ++i)
    for (std::size_t k = 0; k < dt.size(); ++k)
      s[i * dt.size() + k] = std::clamp(ipsaShift(axisV[i], dt[k], off[k]), -size, size);
  return s;
}

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
__attribute__((target("avx2"))) void addTwoAvx2(float* out, const float* a, const float* __restrict b,
                                                int n) {
  int i = 0;
  for (; i + 32 <= n; i += 32) {
    _mm256_storeu_ps(out + i, _mm256_add_ps(_mm256_loadu_ps(a + i), _mm256_loadu_ps(b + i)));
    _mm256_storeu_ps(out + i + 8, _mm256_add_ps(_mm256_loadu_ps(a + i + 8), _mm256_loadu_ps(b + i + 8)));
    _mm256_storeu_ps(out + i + 16, _mm256_add_ps(_mm256_loadu_ps(a + i + 16), _mm256_loadu_ps(b + i + 16)));
    _mm256_storeu_ps(out + i + 24, _mm256_add_ps(_mm256_loadu_ps(a + i + 24), _mm256_loadu_ps(b + i + 24)));
  }
  for (; i + 8 <= n; i += 8)
    _mm256_storeu_ps(out + i, _mm256_add_ps(_mm256_loadu_ps(a + i), _mm256_loadu_ps(b + i)));
  for (; i < n; ++i)
    out[i] = a[i] + b[i];
}
const bool kHaveAvx2 = __builtin_cpu_supports("avx2");
#else
const bool kHaveAvx2 = false;
void addTwoAvx2(float*, const float*, const float*, int) {}
#endif

/// out[0, n) = a[0, n) + b[0, n) (out may be a). AVX2 when the CPU has it.
void addTwo(float* out, const float* a, const float* __restrict b, int n) {
  if (kHaveAvx2) {
    addTwoAvx2(out, a, b, n);
    return;
  }
  for (int i = 0; i < n; ++i)
    out[i] = a[i] + b[i];
}

/// A leaf's stacks, or those of a node with one velocity: its frames summed along the node's implied shifts
/// (the same samples its subtree would add, without building the subtree), zero outside the image.
Planes leafPlanes(const Context& cx, BufferPool& pool, const TreeNode& n, int y0) {
  Planes p;
  p.pw = cx.width + n.x.hi - n.x.lo;
  p.ph = cx.tileRows + n.y.hi - n.y.lo;
  p.nx = static_cast<int>(n.x.v.size());
  const std::size_t area = static_cast<std::size_t>(p.pw) * p.ph;
  p.data = pool.take(n.velocities() * area);
  const int m = n.last - n.first;
  for (std::size_t jy = 0; jy < n.y.v.size(); ++jy) {
    for (std::size_t jx = 0; jx < n.x.v.size(); ++jx) {
      float* out = p.data.data() + (jy * n.x.v.size() + jx) * area;
      for (int k = 0; k < m; ++k) {
        const int f = n.first + k;
        const float* frame = cx.cube.frame(cx.plan.frame[f]);
        const int sx = cx.plan.preX[f] + n.x.pattern[jx * m + k] + n.x.lo;
        const int sy = cx.plan.preY[f] + n.y.pattern[jy * m + k] + n.y.lo + y0;
        const int c0 = std::clamp(-sx, 0, p.pw);
        const int c1 = std::clamp(cx.width - sx, c0, p.pw);
        for (int r = 0; r < p.ph; ++r) {
          const int yi = r + sy;
          float* dst = out + static_cast<std::size_t>(r) * p.pw;
          const bool inside = yi >= 0 && yi < cx.height && c1 > c0;
          if (k == 0 && !inside) {
            std::memset(dst, 0, sizeof(float) * p.pw);
            continue;
          }
          if (!inside) continue;
          const float* src = frame + static_cast<std::size_t>(yi) * cx.width + sx;
          if (k == 0) {
            std::memset(dst, 0, sizeof(float) * c0);
            std::memcpy(dst + c0, src + c0, sizeof(float) * (c1 - c0));
            std::memset(dst + c1, 0, sizeof(float) * (p.pw - c1));
          } else {
            addTwo(dst + c0, dst + c0, src + c0, c1 - c0);
          }
        }
      }
    }
  }
  return p;
}

/// Row r, columns [c0, c0 + count) of the sum of a node's two children for node velocity (jx, jy), into
/// out[0, count).
void combineRow(const TreeNode& n, const TreeNode& l, const TreeNode& rn, const Planes& lp, const Planes& rp,
                int jx, int jy, int r, int c0, int count, float* out) {
  const TreeChoice& lx = n.x.left[jx];
  const TreeChoice& ly = n.y.left[jy];
  const TreeChoice& rx = n.x.right[jx];
  const TreeChoice& ry = n.y.right[jy];
  const float* a = lp.plane(lx.child, ly.child) +
                   static_cast<std::size_t>(n.y.lo + r + ly.offset - l.y.lo) * lp.pw +
                   (n.x.lo + c0 + lx.offset - l.x.lo);
  const float* b = rp.plane(rx.child, ry.child) +
                   static_cast<std::size_t>(n.y.lo + r + ry.offset - rn.y.lo) * rp.pw +
                   (n.x.lo + c0 + rx.offset - rn.x.lo);
  addTwo(out, a, b, count);
}

Planes nodePlanes(const Context& cx, BufferPool& pool, int index, int y0);

/// Children's planes of an internal node, depth-first.
std::pair<Planes, Planes> childPlanes(const Context& cx, BufferPool& pool, const TreeNode& n, int y0) {
  Planes l = nodePlanes(cx, pool, n.left, y0);
  Planes r = nodePlanes(cx, pool, n.right, y0);
  return {std::move(l), std::move(r)};
}

Planes nodePlanes(const Context& cx, BufferPool& pool, int index, int y0) {
  const TreeNode& n = cx.plan.nodes[index];
  if (n.direct()) return leafPlanes(cx, pool, n, y0);
  auto [lp, rp] = childPlanes(cx, pool, n, y0);
  const TreeNode& l = cx.plan.nodes[n.left];
  const TreeNode& rn = cx.plan.nodes[n.right];
  Planes p;
  p.pw = cx.width + n.x.hi - n.x.lo;
  p.ph = cx.tileRows + n.y.hi - n.y.lo;
  p.nx = static_cast<int>(n.x.v.size());
  const std::size_t area = static_cast<std::size_t>(p.pw) * p.ph;
  p.data = pool.take(n.velocities() * area);
  for (int jy = 0; jy < static_cast<int>(n.y.v.size()); ++jy) {
    cx.cancel.throwIfCancelled();
    if (!n.y.used[jy]) continue;
    // Only the window the parents read is built: rows and columns of this velocity's reach.
    const int r0 = n.y.reachLo[jy] - n.y.lo;
    const int r1 = cx.tileRows + n.y.reachHi[jy] - n.y.lo;
    for (int jx = 0; jx < p.nx; ++jx) {
      if (!n.x.used[jx]) continue;
      const int c0 = n.x.reachLo[jx] - n.x.lo;
      const int c1 = cx.width + n.x.reachHi[jx] - n.x.lo;
      float* out = p.data.data() + (static_cast<std::size_t>(jy) * p.nx + jx) * area;
      for (int r = r0; r < r1; ++r)
        combineRow(n, l, rn, lp, rp, jx, jy, r, c0, c1 - c0, out + static_cast<std::size_t>(r) * p.pw + c0);
    }
  }
  pool.give(std::move(lp.data));
  pool.give(std::move(rp.data));
  return p;
}

/// Scans cells [c0, c1) of one root row: SNR with N_in = nInOf(c), best cell, hits.
template <typename NinOf>
void scanSpan(const Context& cx, WorkerState& ws, const float* s, int c0, int c1, int ix, int iy, int y,
              NinOf nInOf) {
  const std::size_t iv = static_cast<std::size_t>(iy) * cx.plan.nodes[0].x.v.size() + ix;
  for (int c = c0; c < c1; ++c) {
    const int nIn = nInOf(c);
    if (nIn < cx.minFrames || nIn <= 0) continue;
    const float snr = s[c] * cx.invNorm[nIn];
    if (snr > ws.bestSnr[iv]) {
      ws.bestSnr[iv] = snr;
      ws.bestX[iv] = c;
      ws.bestY[iv] = y;
    }
    if (snr > cx.threshold) {
      ++ws.hitsTotal;
      if (snr >= ws.floor) ws.hits.push_back(CellHit{snr, s[c], c, y, ix, iy, nIn});
    }
  }
}

void scanRow(const Context& cx, WorkerState& ws, const float* s, int ix, int iy, int y) {
  const int w = cx.width;
  if (cx.registered) {
    const std::size_t n = cx.plan.dt.size();
    ws.nIn.resize(static_cast<std::size_t>(w));
    countFramesInRow(cx.exactX.data() + ix * n, cx.exactY.data() + iy * n, static_cast<int>(n), y, w, cx.height,
                     0, w, ws.diff, ws.nIn.data());
    // Only the region's columns (all of them but in an out-of-core tile).
    scanSpan(cx, ws, s, cx.roi.x0, cx.roi.x0 + cx.roi.width, ix, iy, y,
             [&](int c) { return ws.nIn[static_cast<std::size_t>(c)]; });
    return;
  }
  const int* lx = cx.rx.lo.data() + static_cast<std::size_t>(ix) * w;
  const int* hx = cx.rx.hi.data() + static_cast<std::size_t>(ix) * w;
  const int ly = cx.ry.lo[static_cast<std::size_t>(iy) * cx.height + y];
  const int hy = cx.ry.hi[static_cast<std::size_t>(iy) * cx.height + y];
  const int a = cx.rx.a[ix];
  const int b = cx.rx.b[ix];
  // Only the region's columns [xa, xb) are scanned (all of them but in an out-of-core tile).
  const int xa = cx.roi.x0;
  const int xb = cx.roi.x0 + cx.roi.width;
  const int ca = std::clamp(a, xa, xb);
  const int cb = std::clamp(b, ca, xb);
  (void)w;
  const auto edge = [&](int c) { return std::min(hx[c], hy) - std::max(lx[c], ly); };
  scanSpan(cx, ws, s, xa, ca, ix, iy, y, edge);
  const int nIn = hy - ly;
  if (cb > ca && nIn >= cx.minFrames && nIn > 0) {
    const std::size_t iv = static_cast<std::size_t>(iy) * cx.plan.nodes[0].x.v.size() + ix;
    const float top = detail::maxOf(s + ca, cb - ca) * cx.invNorm[nIn];
    if (top > ws.bestSnr[iv] || top > cx.threshold)
      scanSpan(cx, ws, s, ca, cb, ix, iy, y, [nIn](int) { return nIn; });
  }
  scanSpan(cx, ws, s, cb, xb, ix, iy, y, edge);
}

void trimHits(WorkerState& ws, std::size_t cap) {
  if (ws.hits.size() <= 2 * cap + 1024) return;
  std::nth_element(ws.hits.begin(), ws.hits.begin() + static_cast<std::ptrdiff_t>(cap), ws.hits.end(),
                   [](const CellHit& p, const CellHit& q) { return p.snr > q.snr; });
  ws.hits.resize(cap);
  float lowest = ws.hits.front().snr;
  for (const auto& h : ws.hits)
    lowest = std::min(lowest, h.snr);
  ws.floor = std::max(ws.floor, lowest);
}

/// One tile of rows [y0, y0 + rows): the root's sums per velocity, scanned at once.
void runTile(const Context& cx, WorkerState& ws, int y0) {
  const TreeNode& root = cx.plan.nodes[0];
  auto [lp, rp] = childPlanes(cx, ws.pool, root, y0);
  const TreeNode& l = cx.plan.nodes[root.left];
  const TreeNode& rn = cx.plan.nodes[root.right];
  const int rows = std::min(cx.tileRows, cx.roi.y0 + cx.roi.height - y0);
  ws.row.resize(static_cast<std::size_t>(cx.width) + 8);
  for (int iy = 0; iy < static_cast<int>(root.y.v.size()); ++iy) {
    cx.cancel.throwIfCancelled();
    for (int ix = 0; ix < static_cast<int>(root.x.v.size()); ++ix) {
      for (int r = 0; r < rows; ++r) {
        combineRow(root, l, rn, lp, rp, ix, iy, r, 0, cx.width, ws.row.data());
        scanRow(cx, ws, ws.row.data(), ix, iy, y0 + r);
      }
    }
    trimHits(ws, cx.cap);
  }
  ws.pool.give(std::move(lp.data));
  ws.pool.give(std::move(rp.data));
}

}  // namespace

int treeTileRows(const TreePlan& plan, int width, std::size_t tileBudgetBytes) {
  for (int rows = 64; rows > 1; --rows) {
    if (treeTileBytes(plan, width, rows) <= tileBudgetBytes) return rows;
  }
  return 1;
}

std::size_t treeTileBudgetPerThread(unsigned threads, std::size_t totalBytes) {
  const std::size_t total = totalBytes > 0 ? totalBytes : kTreeBuffersBytes;
  return std::clamp(total / std::max(1u, threads), kTreeMinTileBudgetBytes, kTreeTileBudgetBytes);
}

namespace detail {

namespace {

/// One block of velocities, `grid`, with its plan (the whole grid's, or a block's cut of it: treeSubPlan).
KernelOutput treeSearchBlock(const FrameCube& frames, const TreePlan& plan, const VelocityGrid& grid,
                             const Roi& roi, const TreeRegionParams& p, std::size_t tileBudget,
                             ProgressSink& progress, CancelToken& cancel) {
  SearchParams params;
  params.maxCandidates = p.maxHits;
  Context cx{frames, plan, params, frames.width(), frames.height(), 0, roi, 0.0f, 1, 0, {}, {}, {}, cancel};
  cx.tileRows = treeTileRows(plan, cx.width, tileBudget);
  cx.threshold = static_cast<float>(p.snrThreshold);
  cx.minFrames = p.minFrames;
  cx.cap = p.maxHits;
  const int nf = static_cast<int>(frames.frameCount());
  cx.invNorm.assign(static_cast<std::size_t>(nf) + 1, 0.0f);
  for (int k = 1; k <= nf; ++k)
    cx.invNorm[k] = static_cast<float>(1.0 / (p.sigmaF * std::sqrt(double(k))));
  cx.registered = frames.hasFrameOffsets();
  if (cx.registered) {
    cx.exactX = exactShifts(plan.nodes[0].x.v, plan.dt, plan.ox, cx.width);
    cx.exactY = exactShifts(plan.nodes[0].y.v, plan.dt, plan.oy, cx.height);
  } else {
    cx.rx = axisRanges(plan.nodes[0].x.v, plan.dt, cx.width);
    cx.ry = axisRanges(plan.nodes[0].y.v, plan.dt, cx.height);
  }

  const std::size_t nv = grid.count();
  std::mutex mutex;
  std::vector<std::unique_ptr<WorkerState>> pool;
  const auto acquire = [&] {
    std::lock_guard lock(mutex);
    for (auto& w : pool) {
      if (w) return std::move(w);
    }
    auto w = std::make_unique<WorkerState>();
    w->bestSnr.assign(nv, -std::numeric_limits<float>::infinity());
    w->bestX.assign(nv, -1);
    w->bestY.assign(nv, -1);
    w->floor = cx.threshold;
    return w;
  };
  const std::size_t tiles = static_cast<std::size_t>((roi.height + cx.tileRows - 1) / cx.tileRows);
  std::atomic<std::size_t> done{0};
  progress.report(0.0, "velocity search (tree)");
  parallelFor(
      tiles, 1,
      [&](std::size_t b, std::size_t e) {
    std::unique_ptr<WorkerState> ws = acquire();
    for (std::size_t t = b; t < e; ++t) {
      runTile(cx, *ws, roi.y0 + static_cast<int>(t) * cx.tileRows);
      progress.report(static_cast<double>(done.fetch_add(1) + 1) / static_cast<double>(tiles),
                      "velocity search (tree)");
    }
    std::lock_guard lock(mutex);
    pool.push_back(std::move(ws));
      },
      p.threads);

  KernelOutput out;
  out.map = emptyVelocityMap(grid);
  VelocityMap& map = out.map;
  for (const auto& w : pool) {
    if (!w) continue;
    for (std::size_t iv = 0; iv < nv; ++iv) {
      if (w->bestX[iv] < 0) continue;
      // Ties go to the lowest (y, x), as in the exact backend.
      const bool better =
          map.argX[iv] < 0 || w->bestSnr[iv] > map.maxSnr[iv] ||
          (w->bestSnr[iv] == map.maxSnr[iv] &&
           (w->bestY[iv] < map.argY[iv] || (w->bestY[iv] == map.argY[iv] && w->bestX[iv] < map.argX[iv])));
      if (better) {
        map.maxSnr[iv] = w->bestSnr[iv];
        map.argX[iv] = w->bestX[iv];
        map.argY[iv] = w->bestY[iv];
      }
    }
    out.hitsTotal += w->hitsTotal;
    out.hits.insert(out.hits.end(), w->hits.begin(), w->hits.end());
  }
  return out;
}

}  // namespace

KernelOutput treeSearchRegion(const FrameCube& frames, const VelocityGrid& grid, const Roi& roi,
                              const TreeRegionParams& p, ProgressSink& progress, CancelToken& cancel) {
  const std::shared_ptr<const TreePlan> shared =
      sharedTreePlan(frames.timeOffsetsS(), grid, frames.frameOffsets());
  const TreePlan& whole = *shared;
  // Tile rows from the share of every worker, not of p.threads: the blocks and rows (and so the hits kept per
  // worker) do not depend on how many threads the memory plan allows.
  const std::size_t tileBudget = treeTileBudgetPerThread(workerCount(), p.bufferBytes);
  const TreeBlocks blocks =
      treeVelocityBlocks(whole, frames.width(), roi.height, treeBlockSplitBytes(p.bufferBytes), tileBudget);
  if (blocks.count() == 1) return treeSearchBlock(frames, whole, grid, roi, p, tileBudget, progress, cancel);
  KernelOutput out;
  out.map = emptyVelocityMap(grid);
  VelocityMap& map = out.map;
  const int total = blocks.count();
  for (int by = 0; by < blocks.blocksY; ++by) {
    for (int bx = 0; bx < blocks.blocksX; ++bx) {
      const int b = by * blocks.blocksX + bx;
      int ix0 = 0, iy0 = 0;
      const VelocityGrid sub = treeBlockGrid(grid, blocks, bx, by, ix0, iy0);
      SubProgress part(progress, static_cast<double>(b) / total, static_cast<double>(b + 1) / total);
      const TreePlan plan = treeSubPlan(whole, ix0, sub.nvx, iy0, sub.nvy);
      KernelOutput o = treeSearchBlock(frames, plan, sub, roi, p, tileBudget, part, cancel);
      for (CellHit& h : o.hits) {
        h.ivx += ix0;
        h.ivy += iy0;
      }
      out.hits.insert(out.hits.end(), o.hits.begin(), o.hits.end());
      out.hitsTotal += o.hitsTotal;
      for (int jy = 0; jy < sub.nvy; ++jy) {
        for (int jx = 0; jx < sub.nvx; ++jx) {
          const std::size_t from = static_cast<std::size_t>(jy) * sub.nvx + jx;
          const std::size_t to = static_cast<std::size_t>(iy0 + jy) * grid.nvx + (ix0 + jx);
          map.maxSnr[to] = o.map.maxSnr[from];
          map.argX[to] = o.map.argX[from];
          map.argY[to] = o.map.argY[from];
        }
      }
    }
  }
  // Each block kept its best maxHits cells; the whole search keeps the best maxHits of them, as one tree would.
  if (p.maxHits > 0 && out.hits.size() > p.maxHits) {
    std::nth_element(out.hits.begin(), out.hits.begin() + static_cast<std::ptrdiff_t>(p.maxHits), out.hits.end(),
                     [](const CellHit& a, const CellHit& c) { return a.snr > c.snr; });
    out.hits.resize(p.maxHits);
  }
  return out;
}

}  // namespace detail

SearchResult treeSearch(const FilteredCube& cube, const VelocityGrid& grid, const SearchParams& params,
                        ProgressSink& progress, CancelToken& cancel) {
  const auto start = std::chrono::steady_clock::now();
  SearchResult result = startSearchResult(cube, grid, params, "cpu", SearchMethod::Tree);
  detail::TreeRegionParams p;
  p.sigmaF = cube.sigmaF;
  p.snrThreshold = result.snrThreshold;
  p.minFrames = result.minFrames;
  p.maxHits = params.maxCandidates;
  p.bufferBytes = params.bufferBytes;
  p.threads = params.treeThreads;
  const detail::Roi roi{0, 0, cube.frames.width(), cube.frames.height()};
  detail::KernelOutput out = detail::treeSearchRegion(cube.frames, grid, roi, p, progress, cancel);
  result.map = std::move(out.map);
  result.cellsAboveThreshold = out.hitsTotal;
  setCandidates(result, std::move(out.hits), cube, params);
  result.elapsedS = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  progress.report(1.0, "velocity search (tree)");
  return result;
}

}  // namespace st::search

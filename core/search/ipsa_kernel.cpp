#include "ipsa_kernel.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <mutex>
#include <numeric>
#include <vector>

#include "st/common/error.hpp"
#include "st/common/parallel.hpp"
#include "st/search/ipsa.hpp"

namespace st::search::detail {

namespace {

int roundUp8(int v) {
  return (v + 7) & ~7;
}

/// Frames in time order and their offsets from t_ref.
struct TimeOrder {
  std::vector<std::size_t> frame;  ///< frame index of the k-th frame in time order
  std::vector<double> dt;          ///< its t - t_ref, seconds
  std::vector<double> ox, oy;      ///< its registration offset, px (FrameInfo::offsetXPx/offsetYPx)
  bool registered = false;         ///< some offset is non-zero: shifts need not be monotone in time
};

TimeOrder timeOrder(const FrameCube& cube) {
  const std::vector<double> dt = cube.timeOffsetsS();
  TimeOrder t;
  t.frame.resize(dt.size());
  std::iota(t.frame.begin(), t.frame.end(), 0);
  std::stable_sort(t.frame.begin(), t.frame.end(),
                   [&](std::size_t a, std::size_t b) { return dt[a] < dt[b]; });
  t.dt.resize(dt.size());
  t.ox.resize(dt.size());
  t.oy.resize(dt.size());
  for (std::size_t k = 0; k < dt.size(); ++k) {
    t.dt[k] = dt[t.frame[k]];
    t.ox[k] = cube.info()[t.frame[k]].offsetXPx;
    t.oy[k] = cube.info()[t.frame[k]].offsetYPx;
  }
  t.registered = cube.hasFrameOffsets();
  return t;
}

/// [lo, hi): the time-ordered frames k with a <= s[k] < b, for a monotone (either way) sequence s.
void validRange(const int* s, int n, int a, int b, int& lo, int& hi) {
  if (n == 0) {
    lo = hi = 0;
    return;
  }
  if (s[n - 1] >= s[0]) {
    lo = static_cast<int>(std::lower_bound(s, s + n, a) - s);
    hi = static_cast<int>(std::lower_bound(s, s + n, b) - s);
  } else {
    lo = static_cast<int>(std::partition_point(s, s + n, [b](int v) { return v >= b; }) - s);
    hi = static_cast<int>(std::partition_point(s, s + n, [a](int v) { return v >= a; }) - s);
  }
  if (hi < lo) hi = lo;
}

/// Everything one thread needs for one work item; reused across items.
struct Scratch {
  std::vector<float> acc;          ///< [velocity][row][wp]
  std::vector<float> tile;         ///< [frame in block][tile row][pw]
  std::vector<int> sx, sy;         ///< [velocity][k] shifts in time order
  std::vector<int> loX, hiX;       ///< [velocity][column] valid frame range
  std::vector<int> nInRow, diff;   ///< registered frames: N_in of one row, and its scratch
  std::vector<const float*> ptrs;  ///< kFrameBlock row pointers
  std::vector<CellHit> hits;
};

struct Shared {
  const FrameCube& cube;
  const VelocityGrid& grid;
  const Roi& roi;
  const KernelParams& params;
  TimeOrder order;
  std::vector<float> invNorm;  ///< 1 / (sigma_F sqrt(n)), n = 0..N
  int wp = 0;                  ///< accumulator row length (roi width rounded up to 8)
  int rowTiles = 0;
  int velBlocks = 0;
  std::mutex mutex;
  std::atomic<float> hitFloor{0.0f};
  KernelOutput out;
  int ivBegin = 0;  ///< flat velocity indices searched: [ivBegin, ivEnd)
  int ivEnd = 0;
};

/// Fills the zero-padded tile of frames [k0, k0 + nb) for output rows [y0, y0 + rows) and returns its
/// geometry: rows per frame, the first image row of each frame's tile (syMin), padding and row pitch.
struct TileGeometry {
  int tileRows = 0;
  int pad = 0;
  int pitch = 0;
  int syMin[kFrameBlock] = {};
};

TileGeometry fillTile(Shared& sh, Scratch& s, int nv, int k0, int nb, int y0, int rows) {
  const FrameCube& cube = sh.cube;
  const int n = static_cast<int>(sh.order.frame.size());
  TileGeometry g;
  int spread = 0;
  for (int j = 0; j < nb; ++j) {
    int lo = s.sy[k0 + j];
    int hi = lo;
    for (int v = 0; v < nv; ++v) {
      lo = std::min(lo, s.sy[v * n + k0 + j]);
      hi = std::max(hi, s.sy[v * n + k0 + j]);
      g.pad = std::max(g.pad, std::abs(s.sx[v * n + k0 + j]));
    }
    g.syMin[j] = lo;
    spread = std::max(spread, hi - lo);
  }
  g.tileRows = rows + spread;
  g.pitch = sh.wp + 2 * g.pad;
  const std::size_t need = static_cast<std::size_t>(nb) * g.tileRows * g.pitch;
  if (s.tile.size() < need) s.tile.resize(need);
  const int w = cube.width();
  const int h = cube.height();
  // Tile column t holds image column roi.x0 - pad + t.
  const int tBegin = std::max(0, g.pad - sh.roi.x0);
  const int tEnd = std::max(tBegin, std::min(g.pitch, w - sh.roi.x0 + g.pad));
  for (int j = 0; j < nb; ++j) {
    const float* frame = cube.frame(sh.order.frame[k0 + j]);
    for (int r = 0; r < g.tileRows; ++r) {
      float* dst = s.tile.data() + (static_cast<std::size_t>(j) * g.tileRows + r) * g.pitch;
      const int yImg = y0 + g.syMin[j] + r;
      if (yImg < 0 || yImg >= h || tEnd <= tBegin) {
        std::memset(dst, 0, sizeof(float) * g.pitch);
        continue;
      }
      std::memset(dst, 0, sizeof(float) * tBegin);
      std::memcpy(dst + tBegin, frame + static_cast<std::size_t>(yImg) * w + (sh.roi.x0 - g.pad + tBegin),
                  sizeof(float) * (tEnd - tBegin));
      std::memset(dst + tEnd, 0, sizeof(float) * (g.pitch - tEnd));
    }
  }
  return g;
}

/// Shifts in time order, clamped to +-width / +-height: a sample shifted that far is outside the frame for
/// every output pixel either way, so the statistic and N_in are unchanged while tiles stay small.
void computeShifts(Shared& sh, Scratch& s, int iv0, int nv) {
  const int n = static_cast<int>(sh.order.dt.size());
  const int w = sh.cube.width();
  const int h = sh.cube.height();
  s.sx.resize(static_cast<std::size_t>(nv) * n);
  s.sy.resize(static_cast<std::size_t>(nv) * n);
  for (int v = 0; v < nv; ++v) {
    const int iv = iv0 + v;
    const Velocity vel = sh.grid.at(iv % sh.grid.nvx, iv / sh.grid.nvx);
    for (int k = 0; k < n; ++k) {
      s.sx[v * n + k] = std::clamp(ipsaShift(vel.vx, sh.order.dt[k], sh.order.ox[k]), -w, w);
      s.sy[v * n + k] = std::clamp(ipsaShift(vel.vy, sh.order.dt[k], sh.order.oy[k]), -h, h);
    }
  }
}

/// Per-velocity best cell and hits of one work item, filled by the row scans below.
struct ItemScan {
  std::vector<float> bestSnr;
  std::vector<int> bestX, bestY;
  std::int64_t hitCount = 0;
  float threshold = 0.0f;
  float floor = 0.0f;
};

/// Cells [c0, c1) of one accumulator row with N_in = nIn(c): SNR, best cell, hits.
template <typename NinOf>
void scanSpan(Shared& sh, Scratch& s, ItemScan& scan, const float* acc, int c0, int c1, int v, int iv, int y,
              NinOf nInOf) {
  for (int c = c0; c < c1; ++c) {
    const int nIn = nInOf(c);
    if (nIn < sh.params.minFrames || nIn <= 0) continue;
    const float snr = acc[c] * sh.invNorm[nIn];
    if (snr > scan.bestSnr[v]) {
      scan.bestSnr[v] = snr;
      scan.bestX[v] = sh.roi.x0 + c;
      scan.bestY[v] = y;
    }
    if (snr > scan.threshold) {
      ++scan.hitCount;
      if (snr >= scan.floor) {
        s.hits.push_back(CellHit{snr, acc[c], sh.roi.x0 + c, y, iv % sh.grid.nvx, iv / sh.grid.nvx, nIn});
      }
    }
  }
}

/// Scans the finished accumulators of one item: N_in in closed form, SNR, per-velocity maxima, hits.
/// Columns whose samples are inside the image in every frame (the interior in x) share one N_in per row, so
/// there a vectorised row maximum decides whether any cell needs a closer look.
void evaluate(Shared& sh, Scratch& s, int iv0, int nv, int y0, int rows) {
  const int n = static_cast<int>(sh.order.dt.size());
  const int w = sh.cube.width();
  const int h = sh.cube.height();
  const Roi& roi = sh.roi;
  s.loX.resize(static_cast<std::size_t>(roi.width));
  s.hiX.resize(static_cast<std::size_t>(roi.width));
  s.hits.clear();
  ItemScan scan;
  scan.threshold = static_cast<float>(sh.params.snrThreshold);
  scan.floor = std::max(scan.threshold, sh.hitFloor.load(std::memory_order_relaxed));
  scan.bestSnr.assign(nv, -std::numeric_limits<float>::infinity());
  scan.bestX.assign(nv, -1);
  scan.bestY.assign(nv, -1);
  for (int v = 0; v < nv; ++v) {
    const int* sxv = s.sx.data() + static_cast<std::size_t>(v) * n;
    const int* syv = s.sy.data() + static_cast<std::size_t>(v) * n;
    if (sh.order.registered) {  // shifts not monotone in time: N_in counted frame by frame, per row
      s.nInRow.resize(static_cast<std::size_t>(roi.width));
      for (int r = 0; r < rows; ++r) {
        const int y = y0 + r;
        countFramesInRow(sxv, syv, n, y, w, h, roi.x0, roi.width, s.diff, s.nInRow.data());
        const float* acc = s.acc.data() + (static_cast<std::size_t>(v) * kRowTile + r) * sh.wp;
        scanSpan(sh, s, scan, acc, 0, roi.width, v, iv0 + v, y, [&](int c) { return s.nInRow[c]; });
      }
      continue;
    }
    const auto [sxMin, sxMax] = std::minmax({sxv[0], sxv[n - 1]});  // monotone in time order
    // Interior columns [cA, cB): x + sx in [0, w) for every frame.
    const int cA = std::clamp(-sxMin - roi.x0, 0, roi.width);
    const int cB = std::clamp(w - sxMax - roi.x0, cA, roi.width);
    const auto edgeRange = [&](int c) {
      validRange(sxv, n, -(roi.x0 + c), w - (roi.x0 + c), s.loX[c], s.hiX[c]);
    };
    for (int c = 0; c < cA; ++c)
      edgeRange(c);
    for (int c = cB; c < roi.width; ++c)
      edgeRange(c);
    const int iv = iv0 + v;
    for (int r = 0; r < rows; ++r) {
      const int y = y0 + r;
      int loY = 0, hiY = 0;
      validRange(syv, n, -y, h - y, loY, hiY);
      const float* acc = s.acc.data() + (static_cast<std::size_t>(v) * kRowTile + r) * sh.wp;
      const auto edgeNin = [&](int c) { return std::min(s.hiX[c], hiY) - std::max(s.loX[c], loY); };
      scanSpan(sh, s, scan, acc, 0, cA, v, iv, y, edgeNin);
      const int nIn = hiY - loY;
      if (cB > cA && nIn >= sh.params.minFrames && nIn > 0) {
        const float top = maxOf(acc + cA, cB - cA) * sh.invNorm[nIn];
        if (top > scan.bestSnr[v] || top > scan.threshold) {
          scanSpan(sh, s, scan, acc, cA, cB, v, iv, y, [nIn](int) { return nIn; });
        }
      }
      scanSpan(sh, s, scan, acc, cB, roi.width, v, iv, y, edgeNin);
    }
  }
  std::vector<float>& bestSnr = scan.bestSnr;
  std::vector<int>& bestX = scan.bestX;
  std::vector<int>& bestY = scan.bestY;
  const std::int64_t hitCount = scan.hitCount;
  std::lock_guard lock(sh.mutex);
  VelocityMap& map = sh.out.map;
  for (int v = 0; v < nv; ++v) {
    const int iv = iv0 + v;
    if (bestX[v] < 0) continue;
    // Ties go to the lowest (y, x), so the map does not depend on thread timing.
    const bool better = map.argX[iv] < 0 || bestSnr[v] > map.maxSnr[iv] ||
                        (bestSnr[v] == map.maxSnr[iv] &&
                         (bestY[v] < map.argY[iv] || (bestY[v] == map.argY[iv] && bestX[v] < map.argX[iv])));
    if (better) {
      map.maxSnr[iv] = bestSnr[v];
      map.argX[iv] = bestX[v];
      map.argY[iv] = bestY[v];
    }
  }
  sh.out.hitsTotal += hitCount;
  auto& all = sh.out.hits;
  all.insert(all.end(), s.hits.begin(), s.hits.end());
  const std::size_t cap = sh.params.maxHits;
  if (all.size() > 2 * cap + 1024) {
    std::nth_element(all.begin(), all.begin() + cap, all.end(),
                     [](const CellHit& a, const CellHit& b) { return a.snr > b.snr; });
    all.resize(cap);
    float lowest = all.empty() ? scan.threshold : all.front().snr;
    for (const auto& c : all)
      lowest = std::min(lowest, c.snr);
    sh.hitFloor.store(lowest, std::memory_order_relaxed);
  }
}

void runItem(Shared& sh, Scratch& s, std::size_t item, CancelToken& cancel) {
  // Velocity blocks vary fastest: items taken one after the other (by any thread) read the same frame rows,
  // which then come from L3 rather than memory (a row tile of 1500 frames x 512 px is ~18 MB).
  const int vb = static_cast<int>(item % sh.velBlocks);
  const int rt = static_cast<int>(item / sh.velBlocks);
  const int iv0 = sh.ivBegin + vb * kVelBlock;
  const int nv = std::min<int>(kVelBlock, sh.ivEnd - iv0);
  const int y0 = sh.roi.y0 + rt * kRowTile;
  const int rows = std::min(kRowTile, sh.roi.y0 + sh.roi.height - y0);
  const int n = static_cast<int>(sh.order.dt.size());
  computeShifts(sh, s, iv0, nv);
  s.acc.assign(static_cast<std::size_t>(nv) * kRowTile * sh.wp, 0.0f);
  s.ptrs.resize(kFrameBlock);
  for (int k0 = 0; k0 < n; k0 += kFrameBlock) {
    cancel.throwIfCancelled();
    const int nb = std::min(kFrameBlock, n - k0);
    const TileGeometry g = fillTile(sh, s, nv, k0, nb, y0, rows);
    for (int r = 0; r < rows; ++r) {
      for (int v = 0; v < nv; ++v) {
        for (int j = 0; j < nb; ++j) {
          const std::size_t idx = static_cast<std::size_t>(v) * n + k0 + j;
          const int tileRow = r + s.sy[idx] - g.syMin[j];
          s.ptrs[j] = s.tile.data() + (static_cast<std::size_t>(j) * g.tileRows + tileRow) * g.pitch + g.pad +
                      s.sx[idx];
        }
        addRows(s.acc.data() + (static_cast<std::size_t>(v) * kRowTile + r) * sh.wp, s.ptrs.data(), nb,
                sh.wp);
      }
    }
  }
  evaluate(sh, s, iv0, nv, y0, rows);
}

}  // namespace

KernelOutput runIpsaKernel(const FrameCube& cube, const VelocityGrid& grid, const Roi& roi,
                           const KernelParams& params, ProgressSink& progress, CancelToken& cancel) {
  if (cube.frameCount() == 0) throw InputError("the search got a cube with no frames");
  if (grid.count() == 0) throw InputError("the velocity grid is empty");
  if (roi.width <= 0 || roi.height <= 0 || roi.x0 < 0 || roi.y0 < 0 || roi.x0 + roi.width > cube.width() ||
      roi.y0 + roi.height > cube.height()) {
    throw InputError("search region outside the frames");
  }
  if (!(params.sigmaF > 0.0) || !std::isfinite(params.sigmaF)) {
    throw InputError("sigma_F (noise of a filtered frame) must be positive, got " +
                     std::to_string(params.sigmaF));
  }
  Shared sh{cube, grid, roi, params, timeOrder(cube), {}, roundUp8(roi.width), 0, 0, {}, {}, {}};
  const int n = static_cast<int>(cube.frameCount());
  sh.invNorm.resize(static_cast<std::size_t>(n) + 1, 0.0f);
  for (int k = 1; k <= n; ++k)
    sh.invNorm[k] = static_cast<float>(1.0 / (params.sigmaF * std::sqrt(double(k))));
  sh.rowTiles = (roi.height + kRowTile - 1) / kRowTile;
  const int rowEnd = params.ivyEnd < 0 ? grid.nvy : params.ivyEnd;
  if (params.ivyBegin < 0 || params.ivyBegin >= rowEnd || rowEnd > grid.nvy) {
    throw InputError("velocity rows [" + std::to_string(params.ivyBegin) + ", " + std::to_string(rowEnd) +
                     ") outside the grid's " + std::to_string(grid.nvy));
  }
  sh.ivBegin = params.ivyBegin * grid.nvx;
  sh.ivEnd = rowEnd * grid.nvx;
  sh.velBlocks = (sh.ivEnd - sh.ivBegin + kVelBlock - 1) / kVelBlock;
  sh.hitFloor.store(static_cast<float>(params.snrThreshold));
  sh.out.map.nvx = grid.nvx;
  sh.out.map.nvy = grid.nvy;
  sh.out.map.maxSnr.assign(grid.count(), -std::numeric_limits<float>::infinity());
  sh.out.map.argX.assign(grid.count(), -1);
  sh.out.map.argY.assign(grid.count(), -1);

  const std::size_t items = static_cast<std::size_t>(sh.rowTiles) * sh.velBlocks;
  std::atomic<std::size_t> done{0};
  progress.report(0.0, "velocity search");
  // Scratch buffers reused from item to item and freed with the call (parallelFor's threads outlive it: a
  // thread_local scratch would stay allocated in each of them, outside the search's memory estimate).
  std::mutex scratchMutex;
  std::vector<std::unique_ptr<Scratch>> scratches;
  parallelFor(items, 1, [&](std::size_t b, std::size_t e) {
    std::unique_ptr<Scratch> scratch;
    {
      const std::lock_guard lock(scratchMutex);
      if (!scratches.empty()) {
        scratch = std::move(scratches.back());
        scratches.pop_back();
      }
    }
    if (!scratch) scratch = std::make_unique<Scratch>();
    for (std::size_t i = b; i < e; ++i) {
      runItem(sh, *scratch, i, cancel);
      const std::size_t d = done.fetch_add(1) + 1;
      progress.report(static_cast<double>(d) / static_cast<double>(items), "velocity search");
    }
    const std::lock_guard lock(scratchMutex);
    scratches.push_back(std::move(scratch));
  });
  for (auto& m : sh.out.map.maxSnr) {
    if (!std::isfinite(m)) m = 0.0f;  // velocities where every cell had too few frames
  }
  return std::move(sh.out);
}

std::size_t workingBytes(int width, int height, std::size_t frames, const VelocityGrid& grid,
                         unsigned threads) {
  (void)height;
  const std::size_t wp = static_cast<std::size_t>(roundUp8(width));
  const std::size_t perThread =
      sizeof(float) * (kVelBlock * kRowTile * wp + kFrameBlock * 2 * kRowTile * (wp + 64)) +
      sizeof(int) * kVelBlock * frames * 2;
  const std::size_t map = grid.count() * (sizeof(float) + 2 * sizeof(int));
  const std::size_t hits = 3 * 10000 * sizeof(CellHit);
  return perThread * std::max(1u, threads) + map + hits;
}

}  // namespace st::search::detail

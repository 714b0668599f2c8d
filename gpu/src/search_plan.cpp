#include "search_plan.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "kernel_params.hpp"
#include "st/common/error.hpp"
#include "st/common/parallel.hpp"

namespace st::gpu {
namespace {

int ipsaShift(double v, double dt) {
  return static_cast<int>(std::lround(v * dt));
}

/// Inclusive range [lo, hi] of time-ordered frames k with a <= s[k] < b, s monotone either way.
void validSpan(const int* s, int n, int a, int b, int* out) {
  int lo = 0;
  int hi = 0;
  if (s[n - 1] >= s[0]) {
    lo = static_cast<int>(std::lower_bound(s, s + n, a) - s);
    hi = static_cast<int>(std::lower_bound(s, s + n, b) - s);
  } else {
    lo = static_cast<int>(std::partition_point(s, s + n, [b](int v) { return v >= b; }) - s);
    hi = static_cast<int>(std::partition_point(s, s + n, [a](int v) { return v >= a; }) - s);
  }
  out[0] = lo;
  out[1] = std::max(hi, lo) - 1;
}

/// Shifts [nv][N] in frame order, and the spans from the same shifts in time order.
void buildAxis(const std::vector<double>& vel, const std::vector<double>& dt, const std::vector<int>& order,
               int extent, std::vector<int>& shifts, std::vector<int>& spans) {
  const int n = static_cast<int>(dt.size());
  const int nv = static_cast<int>(vel.size());
  shifts.resize(static_cast<std::size_t>(nv) * n);
  spans.resize(static_cast<std::size_t>(nv) * extent * 2);
  // Velocities in parallel: ~2 x 10^6 binary searches for the paper's problem (5 ms on one core).
  parallelFor(static_cast<std::size_t>(nv), 4, [&](std::size_t lo, std::size_t hi) {
    std::vector<int> sorted(static_cast<std::size_t>(n));
    for (std::size_t i = lo; i < hi; ++i) {
      for (int k = 0; k < n; ++k) {
        shifts[i * n + k] = ipsaShift(vel[i], dt[k]);
        sorted[k] = ipsaShift(vel[i], dt[order[k]]);
      }
      for (int c = 0; c < extent; ++c)
        validSpan(sorted.data(), n, -c, extent - c, &spans[(i * extent + c) * 2]);
    }
  });
}

/// Largest shift difference, over frames, between velocities `len` grid steps apart (tiles can start
/// anywhere).
int maxSpread(const std::vector<int>& shifts, int nv, int n, int len) {
  int spread = 0;
  const int lastStart = std::max(0, nv - len);
  for (int i = 0; i <= lastStart; ++i) {
    const int j = std::min(nv - 1, i + len - 1);
    for (int k = 0; k < n; ++k) {
      spread = std::max(spread, std::abs(shifts[static_cast<std::size_t>(j) * n + k] -
                                         shifts[static_cast<std::size_t>(i) * n + k]));
    }
  }
  return spread;
}

}  // namespace

bool chooseStair(HostPlan& plan, int rows) {
  if (plan.width % 4 != 0 || maxSpread(plan.shiftY, plan.nvy, plan.frameCount, 2) > 1) return false;
  // sm_90 (H100, H200): 228 KiB of shared memory per SM, 1 KiB of it reserved per block, plus the
  // kernel's static barriers; as many frames per stage as fit with 2 (8 rows) or 4 (4 rows) blocks per SM
  // (fewer block-wide barriers per frame: 13 frames instead of 8 for the paper's grid).
  constexpr std::size_t kSmemPerSm = 228 * 1024;
  constexpr std::size_t kPerBlockOverhead = 1024 + 128;
  // Columns a warp reads: its tile, its vx's offset from the 16-byte-aligned origin of the block's vx.
  const int pitch =
      (32 * kStairCols + maxSpread(plan.shiftX, plan.nvx, plan.frameCount, kStairVx) + 3 + 3) / 4 * 4;
  if (pitch > kStairPitch) return false;
  const std::size_t limit = kSmemPerSm / (rows == 4 ? 4 : 2) - kPerBlockOverhead;
  int fs = 16;
  while (fs > 1 && stairSharedBytes(fs, rows) > limit)
    --fs;
  plan.stairRows = rows;
  plan.kernel = HostPlan::Kernel::Stair;
  plan.vtileX = kStairVx;
  plan.vtileY = kStairVy;
  plan.pitch = pitch;
  plan.winRows = rows + kStairVy - 1;
  plan.framesPerStage = fs;
  return true;
}

void chooseTiling(HostPlan& plan, bool allowRow, bool preferRow, bool allowStair) {
  if (allowStair && chooseStair(plan)) return;
  plan.kernel = HostPlan::Kernel::Tiled;
  constexpr std::size_t kTwoBlocksShared = 100 * 1024;
  constexpr std::size_t kOneBlockShared = 220 * 1024;
  const int n = plan.frameCount;
  if (allowRow && plan.width % 4 == 0 &&
      maxSpread(plan.shiftX, plan.nvx, n, kRowVelocities) + 3 <= kRowMaxOffset) {
    // Groups per block: more groups share one window, but leave more warps idle when nvx is not a
    // multiple of 8 G. Rates per useful velocity measured on an H200 (2026-11-22, paper's problem): row
    // kernel 2.93e12 additions/s with 1 group, 3.3e12 with 8; tiled kernel 2.96e12. The row kernel is
    // taken only when its estimate beats the tiled kernel's.
    const double tiledRate = 2.96e12 * plan.nvx / (double((plan.nvx + 7) / 8) * 8);
    double bestRate = preferRow ? 0.0 : tiledRate;
    for (const int g : {8, 4, 2, 1}) {
      const int perTile = kRowVelocities * g;
      const int pitch = 140 + (maxSpread(plan.shiftX, plan.nvx, n, perTile) + 3) / 4 * 4;
      const int rows = 2 * (8 / g);
      int fs = 16;
      while (fs > 1 && rowSharedBytes(pitch, rows, fs) > kTwoBlocksShared)
        fs /= 2;
      if (rowSharedBytes(pitch, rows, fs) > kTwoBlocksShared) continue;
      const double useful = double(plan.nvx) / (double((plan.nvx + perTile - 1) / perTile) * perTile);
      const double rate = (2.93e12 + (3.3e12 - 2.93e12) * (g - 1) / 7.0) * useful;
      if (rate > bestRate) {
        bestRate = rate;
        plan.kernel = HostPlan::Kernel::Row;
        plan.rowGroups = g;
        plan.vtileX = perTile;
        plan.vtileY = 1;
        plan.pitch = pitch;
        plan.winRows = rows;
        plan.framesPerStage = fs;
      }
    }
    if (plan.kernel == HostPlan::Kernel::Row) return;
  }
  const int tw = tiledTileWidth(plan.tiledMode);
  long best = -1;
  for (const int vx : {8, 4, 2, 1}) {
    const int vy = kVelPerBlock / vx;
    const int sx = maxSpread(plan.shiftX, plan.nvx, n, vx);
    const int sy = maxSpread(plan.shiftY, plan.nvy, n, vy);
    const long area = static_cast<long>(tw + sx) * (kTileH + sy);
    if (best < 0 || area < best) {
      best = area;
      plan.vtileX = vx;
      plan.vtileY = vy;
      plan.pitch = tw + sx;
      plan.winRows = kTileH + sy;
    }
  }
  for (const int fs : {4, 2, 1}) {
    if (tiledSharedBytes(plan.pitch, plan.winRows, fs) <= kTwoBlocksShared) {
      plan.framesPerStage = fs;
      plan.kernel = HostPlan::Kernel::Tiled;
      return;
    }
  }
  plan.framesPerStage = 1;
  plan.kernel = tiledSharedBytes(plan.pitch, plan.winRows, 1) <= kOneBlockShared ? HostPlan::Kernel::Tiled
                                                                                 : HostPlan::Kernel::Naive;
}

HostPlan makeHostPlan(const search::FilteredCube& cube, const search::VelocityGrid& grid, double threshold,
                      int minFrames) {
  const FrameCube& f = cube.frames;
  HostPlan plan;
  plan.width = f.width();
  plan.height = f.height();
  plan.frameCount = static_cast<int>(f.frameCount());
  plan.nvx = grid.nvx;
  plan.nvy = grid.nvy;
  const std::vector<double> dt = f.timeOffsetsS();
  std::vector<int> order(dt.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return dt[a] < dt[b]; });
  std::vector<double> vx(static_cast<std::size_t>(grid.nvx));
  std::vector<double> vy(static_cast<std::size_t>(grid.nvy));
  for (int i = 0; i < grid.nvx; ++i)
    vx[i] = grid.at(i, 0).vx;
  for (int i = 0; i < grid.nvy; ++i)
    vy[i] = grid.at(0, i).vy;
  buildAxis(vx, dt, order, plan.width, plan.shiftX, plan.spanX);
  buildAxis(vy, dt, order, plan.height, plan.shiftY, plan.spanY);
  plan.invNorm.assign(static_cast<std::size_t>(plan.frameCount) + 1, 0.0f);
  for (int k = 1; k <= plan.frameCount; ++k) {
    plan.invNorm[k] = static_cast<float>(1.0 / (cube.sigmaF * std::sqrt(static_cast<double>(k))));
  }
  plan.snrThreshold = static_cast<float>(threshold);
  plan.minFrames = minFrames;
  chooseTiling(plan, true, false, true);
  return plan;
}

void validateForGpu(const search::FilteredCube& cube) {
  const std::size_t n = cube.frames.frameCount();
  if (n > 0x7FFFFFFF / 4) throw InputError("too many frames for the CUDA backend: " + std::to_string(n));
  if (cube.frames.pixels().size() != n * cube.frames.framePixels()) {
    throw InputError("the cube's pixel buffer does not match its frames (" +
                     std::to_string(cube.frames.pixels().size()) + " values)");
  }
}

}  // namespace st::gpu

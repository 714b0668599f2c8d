#include "search_plan.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "kernel_params.hpp"
#include "st/common/error.hpp"

namespace st::gpu {
namespace {

/// round(o + v dt), halves away from zero: search::ipsaShift(v, dt, o) (o = 0 unless registered).
int ipsaShift(double v, double dt, double o) {
  return static_cast<int>(std::lround(o + v * dt));
}

/// For every column (or row) c in [0, extent): the inclusive range [lo, hi] of time-ordered frames k with
/// -c <= s[k] < extent - c, i.e. those that keep c inside the frame (hi < lo: none). `s` is monotone either
/// way; one sweep over the frames and the columns (the bounds move one way as c moves the other).
void validSpans(const int* s, int n, int extent, int* out) {
  int lo = 0;
  int hi = 0;
  auto put = [&](int c) {
    out[2 * c] = lo;
    out[2 * c + 1] = std::max(hi, lo) - 1;
  };
  if (s[n - 1] >= s[0]) {  // non-decreasing: lo = first s >= -c, hi = first s >= extent - c
    for (int c = extent - 1; c >= 0; --c) {
      while (lo < n && s[lo] < -c)
        ++lo;
      while (hi < n && s[hi] < extent - c)
        ++hi;
      put(c);
    }
  } else {  // non-increasing: lo = first s < extent - c, hi = first s < -c
    for (int c = 0; c < extent; ++c) {
      while (lo < n && s[lo] >= extent - c)
        ++lo;
      while (hi < n && s[hi] >= -c)
        ++hi;
      put(c);
    }
  }
}

/// Shifts [nv][N] in frame order, and the spans from the same shifts in time order.
void buildAxis(const std::vector<double>& vel, const std::vector<double>& dt, const std::vector<double>& off,
               const std::vector<int>& order, int extent, std::vector<int>& shifts, std::vector<int>& spans) {
  const int n = static_cast<int>(dt.size());
  const int nv = static_cast<int>(vel.size());
  shifts.resize(static_cast<std::size_t>(nv) * n);
  spans.resize(static_cast<std::size_t>(nv) * extent * 2);
  std::vector<int> sorted(static_cast<std::size_t>(n));
  for (std::size_t i = 0; i < static_cast<std::size_t>(nv); ++i) {
    for (int k = 0; k < n; ++k) {
      shifts[i * n + k] = ipsaShift(vel[i], dt[k], off[k]);
      sorted[k] = ipsaShift(vel[i], dt[order[k]], off[order[k]]);
    }
    validSpans(sorted.data(), n, extent, &spans[i * extent * 2]);
  }
}

/// Registered frames: [nv][extent][words] bit n set when frame n's shift keeps position c in [0, extent).
std::vector<unsigned> frameMasks(const std::vector<int>& shifts, int nv, int n, int extent, int words) {
  std::vector<unsigned> m(static_cast<std::size_t>(nv) * extent * words, 0u);
  for (std::size_t i = 0; i < static_cast<std::size_t>(nv); ++i) {
    for (int k = 0; k < n; ++k) {
      const int s = shifts[i * n + k];
      const int lo = std::clamp(-s, 0, extent), hi = std::clamp(extent - s, lo, extent);
      for (int c = lo; c < hi; ++c)
        m[(i * extent + c) * words + k / 32] |= 1u << (k % 32);
    }
  }
  return m;
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

bool chooseStairHalf(HostPlan& plan, int maxFramesPerStage) {
  if (plan.kernel != HostPlan::Kernel::Stair || plan.stairRows != 8 || plan.stairPipe) return false;
  if (plan.pitch - 32 > kStairHalfPitch) return false;  // pairs (x, x + 32): 32 words fewer than floats
  constexpr std::size_t kLimit = 228 * 1024 / 2 - (1024 + 128);
  const int cap = maxFramesPerStage > 0 ? maxFramesPerStage : kStairHalfDefaultStage;
  int fs = std::min(cap, kStairHalfMaxStage);
  while (fs > 1 && stairHalfSharedBytes(fs) > kLimit)
    --fs;
  plan.halfFrames = true;
  plan.halfFramesPerStage = fs;
  plan.halfScale =
      static_cast<float>(std::ldexp(1.0, -static_cast<int>(std::lround(std::log2(plan.sigmaF)))));
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
  std::vector<double> ox(dt.size(), 0.0), oy(dt.size(), 0.0);
  for (std::size_t k = 0; k < dt.size(); ++k) {
    ox[k] = f.info()[k].offsetXPx;
    oy[k] = f.info()[k].offsetYPx;
  }
  buildAxis(vx, dt, ox, order, plan.width, plan.shiftX, plan.spanX);
  buildAxis(vy, dt, oy, order, plan.height, plan.shiftY, plan.spanY);
  if (f.hasFrameOffsets()) {  // shifts not monotone in time: N_in from per-frame masks, not spans
    plan.maskWords = (plan.frameCount + 31) / 32;
    plan.maskX = frameMasks(plan.shiftX, plan.nvx, plan.frameCount, plan.width, plan.maskWords);
    plan.maskY = frameMasks(plan.shiftY, plan.nvy, plan.frameCount, plan.height, plan.maskWords);
  }
  plan.sigmaF = cube.sigmaF;
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

// The static sources' masks applied to a cube (detect/static_sources.hpp): the masked reference positions
// zeroed in every frame, the pixels without a measured background, and the single-frame sources. Split from
// static_sources.cpp (the search for the sources), which builds the masks.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#endif

#include "st/common/parallel.hpp"
#include "st/detect/static_sources.hpp"

namespace st::detect {

std::vector<std::pair<int, int>> maskedPositions(const MovingMask& mask) {
  std::vector<std::pair<int, int>> set;
  const auto& c = mask.canvas();
  for (int j = 0; j < mask.canvasHeight(); ++j)
    for (int i = 0; i < mask.canvasWidth(); ++i)
      if (c[static_cast<std::size_t>(j) * mask.canvasWidth() + i])
        set.emplace_back(mask.x0() + i, mask.y0() + j);
  return set;
}

std::vector<std::uint8_t> coveredInSomeFrame(const MovingMask& mask, int w, int h) {
  std::vector<std::uint8_t> kept(static_cast<std::size_t>(w) * h, 0);
  if (mask.empty()) return kept;
  std::vector<std::pair<int, int>> shifts;
  for (std::size_t n = 0; n < mask.frameCount(); ++n)
    shifts.emplace_back(mask.shiftX(n), mask.shiftY(n));
  std::sort(shifts.begin(), shifts.end());
  shifts.erase(std::unique(shifts.begin(), shifts.end()), shifts.end());
  const auto& c = mask.canvas();
  for (int j = 0; j < mask.canvasHeight(); ++j)
    for (int i = 0; i < mask.canvasWidth(); ++i) {
      if (!c[static_cast<std::size_t>(j) * mask.canvasWidth() + i]) continue;
      for (const auto& [sx, sy] : shifts) {
        const int x = mask.x0() + i + sx, y = mask.y0() + j + sy;
        if (x >= 0 && y >= 0 && x < w && y < h) kept[static_cast<std::size_t>(y) * w + x] = 1;
      }
    }
  return kept;
}

std::size_t zeroMasked(FrameCube& cube, const MovingMask& mask, ProgressSink& progress, CancelToken& cancel) {
  if (mask.empty()) return 0;
  // The set reference positions, listed once.
  const std::vector<std::pair<int, int>> set = maskedPositions(mask);
  std::vector<std::size_t> perFrame(cube.frameCount(), 0);
  const int w = cube.width(), h = cube.height();
  parallelFor(cube.frameCount(), 16, [&](std::size_t n0, std::size_t n1) {
    for (std::size_t n = n0; n < n1; ++n) {
      cancel.throwIfCancelled();
      float* f = cube.frame(n);
      for (const auto& [X, Y] : set) {
        const int x = X + mask.shiftX(n), y = Y + mask.shiftY(n);
        if (x < 0 || y < 0 || x >= w || y >= h) continue;
        f[static_cast<std::size_t>(y) * w + x] = 0.0f;
        ++perFrame[n];
      }
    }
    progress.report(static_cast<double>(n1) / cube.frameCount(), "zero static sources");
  });
  std::size_t total = 0;
  for (auto v : perFrame)
    total += v;
  return total;
}

std::size_t zeroUnmeasured(FrameCube& cube, const std::vector<std::uint8_t>& unmeasured,
                           const MovingMask& keep) {
  const int w = cube.width(), h = cube.height();
  if (unmeasured.size() != cube.framePixels()) return 0;
  // Pixels `keep` covers in some frame.
  const std::vector<std::uint8_t> kept = coveredInSomeFrame(keep, w, h);
  std::size_t zeroed = 0;
  for (std::size_t i = 0; i < kept.size(); ++i) {
    if (kept[i] || !unmeasured[i]) continue;
    bool any = false;
    for (std::size_t n = 0; n < cube.frameCount(); ++n) {
      float& v = cube.frame(n)[i];
      any |= v != 0.0f;
      v = 0.0f;
    }
    zeroed += any;
  }
  return zeroed;
}

namespace {

// The pixels i (in order) with may[i] set and !(f[i] < thr[i]).
void findSeedsScalar(const float* f, const float* thr, const std::int32_t* may, std::size_t i0,
                     std::size_t np, std::vector<int>& seeds) {
  for (std::size_t i = i0; i < np; ++i)
    if (may[i] && !(f[i] < thr[i])) seeds.push_back(static_cast<int>(i));
}

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define ST_STATIC_SOURCES_AVX2 1
__attribute__((target("avx2"))) std::size_t findSeedsAvx2(const float* f, const float* thr,
                                                          const std::int32_t* may, std::size_t np,
                                                          std::vector<int>& seeds) {
  std::size_t i = 0;
  for (; i + 8 <= np; i += 8) {
    const __m256 lt = _mm256_cmp_ps(_mm256_loadu_ps(f + i), _mm256_loadu_ps(thr + i), _CMP_LT_OQ);
    const __m256 seed = _mm256_andnot_ps(
        lt, _mm256_castsi256_ps(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(may + i))));
    unsigned bits = static_cast<unsigned>(_mm256_movemask_ps(seed));
    while (bits) {
      seeds.push_back(static_cast<int>(i) + __builtin_ctz(bits));
      bits &= bits - 1;
    }
  }
  return i;
}
#endif

void findSeeds(const float* f, const float* thr, const std::int32_t* may, std::size_t np,
               std::vector<int>& seeds) {
  std::size_t i0 = 0;
#ifdef ST_STATIC_SOURCES_AVX2
  static const bool avx2 = __builtin_cpu_supports("avx2") != 0;
  if (avx2) i0 = findSeedsAvx2(f, thr, may, np, seeds);
#endif
  findSeedsScalar(f, thr, may, i0, np, seeds);
}

}  // namespace

SingleFrameSources zeroSingleFrameSources(FrameCube& cube, const Image& sigma, double sigmaN, double snr,
                                          int radiusPx, ProgressSink& progress, CancelToken& cancel,
                                          const MovingMask* keep) {
  SingleFrameSources out;
  out.seedsPerFrame.assign(cube.frameCount(), 0);
  out.zeroedPerFrame.assign(cube.frameCount(), 0);
  const int w = cube.width(), h = cube.height();
  const std::size_t np = cube.framePixels();
  const bool perPixel = sigma.size() == np;
  const int r2 = radiusPx * radiusPx;
  const bool useKeep = keep && !keep->empty();
  // Per pixel, the float threshold equivalent to the double test f < snr * s (the smallest float >= snr * s:
  // NaN stays NaN, so NaN samples and thresholds seed as before) and whether s > 0 lets it seed at all.
  std::vector<float> thr(np);
  std::vector<std::int32_t> may(np);
  for (std::size_t i = 0; i < np; ++i) {
    const double s = perPixel ? sigma.pixels[i] : sigmaN;
    const double t = snr * s;
    float tf = static_cast<float>(t);
    if (static_cast<double>(tf) < t) tf = std::nextafter(tf, std::numeric_limits<float>::infinity());
    thr[i] = tf;
    may[i] = s <= 0 ? 0 : -1;
  }
  parallelFor(cube.frameCount(), 8, [&](std::size_t n0, std::size_t n1) {
    std::vector<int> seeds;
    for (std::size_t n = n0; n < n1; ++n) {
      cancel.throwIfCancelled();
      float* f = cube.frame(n);
      seeds.clear();
      findSeeds(f, thr.data(), may.data(), np, seeds);
      if (useKeep) {
        std::size_t kept = 0;
        for (const int i : seeds)
          if (!keep->covers(n, i % w, i / w)) seeds[kept++] = i;
        seeds.resize(kept);
      }
      out.seedsPerFrame[n] = seeds.size();
      for (int p : seeds) {
        const int px = p % w, py = p / w;
        for (int dy = -radiusPx; dy <= radiusPx; ++dy)
          for (int dx = -radiusPx; dx <= radiusPx; ++dx) {
            const int x = px + dx, y = py + dy;
            if (x < 0 || y < 0 || x >= w || y >= h || dx * dx + dy * dy > r2) continue;
            float& v = f[static_cast<std::size_t>(y) * w + x];
            if (v != 0.0f) {
              v = 0.0f;
              ++out.zeroedPerFrame[n];
            }
          }
      }
    }
    progress.report(static_cast<double>(n1) / cube.frameCount(), "single-frame sources");
  });
  return out;
}

}  // namespace st::detect

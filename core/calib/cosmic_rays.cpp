#include "st/calib/cosmic_rays.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <limits>
#include <mutex>
#include <optional>
#include <vector>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#endif

#include "st/common/parallel.hpp"
#include "st/detect/moving_mask.hpp"
#include "st/detect/sky_stack.hpp"
#include "st/stats/order_statistic.hpp"
#include "st/stats/sigma_clip.hpp"

namespace st::calib {

std::vector<detect::SkyStackCache::Range> protectionRanges(std::size_t frames, int protectBlocks) {
  std::vector<detect::SkyStackCache::Range> out;
  if (frames == 0) return out;
  const std::size_t blocks = std::clamp<std::size_t>(static_cast<std::size_t>(protectBlocks), 1, frames);
  for (std::size_t b = 0; b < blocks; ++b)
    out.emplace_back(frames * b / blocks, frames * (b + 1) / blocks);
  return out;
}

namespace {

// The two frames a frame is compared with: its neighbours, or the next two at either end.
std::pair<std::size_t, std::size_t> neighbours(std::size_t n, std::size_t nf) {
  if (n == 0) return {1, 2};
  if (n + 1 == nf) return {nf - 2, nf - 3};
  return {n - 1, n + 1};
}

// The temporal reference of a pixel: the two nearest frames, sampled both at the same detector pixel and
// where the same patch of sky lies in them (integer shifts round(v (t_n - t_ref)) of the sky rate, the
// MovingMask convention). A cosmic ray stands above all four samples; a star drifting by ~1 px per frame
// (paper-neo) does not stand above itself, nor a hot pixel or bad column above itself. Without drift the
// two pairs coincide. A sample outside its frame or masked is left out; a pixel needs both detector-frame
// samples and is never flagged otherwise.
class TimeReference {
 public:
  TimeReference(const FrameCube& cube, const detect::MovingMask& geom)
      : m_cube(cube), m_geom(geom), m_np(cube.framePixels()), m_nf(cube.frameCount()) {}

  /// Largest of the reference samples of pixel (x, y) of frame n, and the mean of the two detector-frame
  /// ones (the fill value); false when a detector-frame sample is unusable.
  bool at(std::size_t n, int x, int y, float* maxOut, float* meanOut) const {
    const auto [a, b] = neighbours(n, m_nf);
    float va = 0.0f, vb = 0.0f;
    if (!sample(a, x, y, &va) || !sample(b, x, y, &vb)) return false;
    *maxOut = std::max(va, vb);
    *meanOut = 0.5f * (va + vb);
    for (const std::size_t r : {a, b}) {
      float v = 0.0f;
      const int xr = x + m_geom.shiftX(r) - m_geom.shiftX(n), yr = y + m_geom.shiftY(r) - m_geom.shiftY(n);
      if ((xr != x || yr != y) && sample(r, xr, yr, &v)) *maxOut = std::max(*maxOut, v);
    }
    return true;
  }

 private:
  bool sample(std::size_t a, int x, int y, float* v) const {
    if (x < 0 || y < 0 || x >= m_cube.width() || y >= m_cube.height()) return false;
    const std::size_t i = a * m_np + static_cast<std::size_t>(y) * m_cube.width() + x;
    if (!m_cube.mask().empty() && m_cube.mask()[i]) return false;
    *v = m_cube.pixels()[i];
    return true;
  }
  const FrameCube& m_cube;
  const detect::MovingMask& m_geom;
  std::size_t m_np, m_nf;
};

// Protected positions (at t_ref, following the sky rate) and the star signal there: the smallest block mean
// above the local background, counts per frame.
struct Protection {
  detect::MovingMask mask;
  std::vector<float> signal;     // on the mask's canvas
  int stacks = 0, provided = 0;  // stacks at the sky rate used, and made by the provider
  double stackSeconds = 0.0;     // making them
  [[nodiscard]] float signalAt(std::size_t n, int x, int y) const {
    const int i = x - mask.shiftX(n) - mask.x0(), j = y - mask.shiftY(n) - mask.y0();
    if (i < 0 || j < 0 || i >= mask.canvasWidth() || j >= mask.canvasHeight()) return 0.0f;
    return signal[static_cast<std::size_t>(j) * mask.canvasWidth() + i];
  }
};

// Canvas pixels per task of the element-wise loops (a canvas is ~1M pixels: ~16 tasks).
constexpr std::size_t kCanvasChunk = std::size_t{1} << 16;

Protection protection(const FrameCube& cube, const CosmicRayParams& params, double sigma,
                      ProgressSink& progress, CancelToken& cancel,
                      const detect::SkyStackCache::Provider* stacks) {
  detect::MovingMask mask(cube, params.skyRate);
  const std::vector<detect::SkyStackCache::Range> ranges =
      protectionRanges(cube.frameCount(), params.protectBlocks);
  const int blocks = static_cast<int>(ranges.size());
  // A block observes a canvas pixel when enough of its frames cover it (a drifting star is in the field for
  // part of the night only); blocks that do not observe it neither protect nor veto.
  std::vector<float> minSnr, minMean;
  std::vector<std::uint8_t> observed;
  int provided = 0;
  double stackSeconds = 0.0;
  for (int b = 0; b < blocks; ++b) {
    SubProgress sub(progress, 0.5 * b / blocks, 0.5 * (b + 1) / blocks);
    const auto [f0, f1] = ranges[static_cast<std::size_t>(b)];
    const auto t0 = std::chrono::steady_clock::now();
    std::optional<detect::SkyStack> made;
    if (stacks && *stacks) {
      made = (*stacks)(cube, params.skyRate, 0.0, f0, f1);
      cancel.throwIfCancelled();
      provided += made ? 1 : 0;
    }
    if (!made) made = detect::stackAtSkyRate(cube, params.skyRate, 0.0, sub, cancel, f0, f1);
    stackSeconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const detect::SkyStack& s = *made;
    const Image local = detect::meshBackground(s.mean, s.count, 32);
    const float minCount = std::max(3.0f, 0.1f * static_cast<float>(f1 - f0));
    if (minSnr.empty()) {
      minSnr.assign(s.mean.size(), 1e30f);
      minMean.assign(s.mean.size(), 1e30f);
      observed.assign(s.mean.size(), 0);
    }
    parallelFor(s.mean.size(), kCanvasChunk, [&](std::size_t i0, std::size_t i1) {
      for (std::size_t i = i0; i < i1; ++i) {
        if (s.count.pixels[i] < minCount) continue;
        const float excess = s.mean.pixels[i] - local.pixels[i];
        minSnr[i] = std::min(minSnr[i], static_cast<float>(excess * std::sqrt(s.count.pixels[i]) / sigma));
        minMean[i] = std::min(minMean[i], excess);
        ++observed[i];
      }
    });
  }
  // A hit that protects itself (the only observing block) is still flagged: its block mean, the signal it
  // must exceed, is its own amplitude divided by the block's frames covering it (>= 3).
  const int cw = mask.canvasWidth();
  parallelFor(static_cast<std::size_t>(mask.canvasHeight()), 16, [&](std::size_t j0, std::size_t j1) {
    for (int j = static_cast<int>(j0); j < static_cast<int>(j1); ++j)
      for (int i = 0; i < cw; ++i) {
        const std::size_t k = static_cast<std::size_t>(j) * cw + i;
        if (observed[k] > 0 && minSnr[k] >= params.protectSnr) mask.set(mask.x0() + i, mask.y0() + j);
      }
  });
  mask.dilate(params.protectDilatePx);
  Protection p{std::move(mask), std::vector<float>(minMean.size(), 0.0f), blocks, provided, stackSeconds};
  parallelFor(minMean.size(), kCanvasChunk, [&](std::size_t i0, std::size_t i1) {
    for (std::size_t i = i0; i < i1; ++i)
      if (p.mask.canvas()[i] && observed[i] > 0) p.signal[i] = std::max(0.0f, minMean[i]);
  });
  return p;
}

// The pixels i (in order) that pass isHit's pre-test: not f - max(fa, fb) <= thr (NaN passes).
void preTestScalar(const float* f, const float* fa, const float* fb, std::size_t i0, std::size_t np,
                   float thr, std::vector<std::uint32_t>& out) {
  for (std::size_t i = i0; i < np; ++i)
    if (!(f[i] - std::max(fa[i], fb[i]) <= thr)) out.push_back(static_cast<std::uint32_t>(i));
}

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define ST_COSMIC_RAYS_AVX2 1
// max_ps(b, a) is std::max(a, b) (a when either is NaN); NLE_UQ is !(x <= thr).
__attribute__((target("avx2"))) std::size_t preTestAvx2(const float* f, const float* fa, const float* fb,
                                                        std::size_t np, float thr,
                                                        std::vector<std::uint32_t>& out) {
  const __m256 t = _mm256_set1_ps(thr);
  std::size_t i = 0;
  for (; i + 8 <= np; i += 8) {
    const __m256 mx = _mm256_max_ps(_mm256_loadu_ps(fb + i), _mm256_loadu_ps(fa + i));
    const __m256 d = _mm256_sub_ps(_mm256_loadu_ps(f + i), mx);
    unsigned bits = static_cast<unsigned>(_mm256_movemask_ps(_mm256_cmp_ps(d, t, _CMP_NLE_UQ)));
    while (bits) {
      out.push_back(static_cast<std::uint32_t>(i) + static_cast<std::uint32_t>(__builtin_ctz(bits)));
      bits &= bits - 1;
    }
  }
  return i;
}
#endif

void preTest(const float* f, const float* fa, const float* fb, std::size_t np, float thr,
             std::vector<std::uint32_t>& out) {
  std::size_t i0 = 0;
#ifdef ST_COSMIC_RAYS_AVX2
  static const bool avx2 = __builtin_cpu_supports("avx2") != 0;
  if (avx2) i0 = preTestAvx2(f, fa, fb, np, thr, out);
#endif
  preTestScalar(f, fa, fb, i0, np, thr, out);
}

// The pixels i of frame n (in order) whose bit is set in `words` (frame n's flat indices [n np, (n + 1) np)).
void preTestFromWords(const CosmicRayPreTestWords& words, std::size_t n, std::size_t np,
                      std::vector<std::uint32_t>& out) {
  const std::size_t k0 = n * np, k1 = k0 + np;
  auto it = std::lower_bound(words.index.begin(), words.index.end(), std::uint64_t{k0 / 32});
  for (auto j = static_cast<std::size_t>(it - words.index.begin());
       j < words.index.size() && words.index[j] * 32 < k1; ++j) {
    std::uint32_t b = words.bits[j];
    while (b) {
      const std::size_t k = words.index[j] * 32 + static_cast<std::size_t>(__builtin_ctz(b));
      b &= b - 1;
      if (k >= k0 && k < k1) out.push_back(static_cast<std::uint32_t>(k - k0));
    }
  }
}

// Value exceeded by a fraction `q` of `v`.
float upperQuantile(const std::vector<float>& v, double q) {
  const auto k = static_cast<std::size_t>(std::floor((1.0 - q) * static_cast<double>(v.size() - 1)));
  return stats::kthSmallest(v.data(), v.size(), k);
}

}  // namespace

CosmicRayPreTestWords cosmicRayPreTestWords(const FrameCube& cube, float thr) {
  const std::size_t nf = cube.frameCount(), np = cube.framePixels();
  CosmicRayPreTestWords out;
  if (nf < 3) return out;
  const float* px = cube.pixels().data();
  std::vector<std::uint32_t> pass;
  for (std::size_t n = 0; n < nf; ++n) {
    const auto [a, b] = neighbours(n, nf);
    pass.clear();
    preTest(px + n * np, px + a * np, px + b * np, np, thr, pass);
    for (const std::uint32_t i : pass) {
      const std::uint64_t k = n * np + i;
      if (out.index.empty() || out.index.back() != k / 32) {
        out.index.push_back(k / 32);
        out.bits.push_back(0);
      }
      out.bits.back() |= std::uint32_t{1} << (k % 32);
    }
  }
  return out;
}

TailModel fitExcessTail(const FrameCube& cube, Velocity skyRate,
                        const std::function<bool(std::size_t, int, int)>& skip) {
  const std::size_t nf = cube.frameCount();
  TailModel t;
  if (nf < 3) return t;
  const detect::MovingMask geom(cube, skyRate);
  const TimeReference ref(cube, geom);
  const std::size_t np = cube.framePixels();
  const int w = cube.width();
  const auto& mask = cube.mask();
  const std::size_t frames = std::min<std::size_t>(nf, 8);
  // The sampled frames' excesses, in tasks of one frame's band of rows (one task per frame left half of 16
  // threads idle), each into its own part of one buffer (the serial loop's memory), then moved together in
  // frame and band order: the samples, so the quantiles, are the serial loop's.
  const int h = cube.height();
  const std::size_t bands = static_cast<std::size_t>(std::clamp(h / 32, 1, 8));
  std::vector<float> d(frames * np);
  std::vector<std::size_t> count(frames * bands, 0);
  parallelFor(frames * bands, 1, [&](std::size_t t0, std::size_t t1) {
    for (std::size_t task = t0; task < t1; ++task) {
      const std::size_t k = task / bands, band = task % bands;
      const std::size_t n = (nf - 1) * k / std::max<std::size_t>(1, frames - 1);
      const float* f = cube.frame(n);
      const std::size_t i0 = static_cast<std::size_t>(h) * band / bands * w;
      const std::size_t i1 = static_cast<std::size_t>(h) * (band + 1) / bands * w;
      float* out = d.data() + k * np + i0;
      std::size_t kept = 0;  // a local count: neighbouring tasks' counters share a cache line
      for (std::size_t i = i0; i < i1; ++i) {
        const int x = static_cast<int>(i % w), y = static_cast<int>(i / w);
        float mx = 0.0f, mean = 0.0f;
        if (!mask.empty() && mask[n * np + i]) continue;
        if ((skip && skip(n, x, y)) || !ref.at(n, x, y, &mx, &mean)) continue;
        out[kept++] = f[i] - mx;
      }
      count[task] = kept;
    }
  });
  std::size_t kept = 0;
  for (std::size_t task = 0; task < frames * bands; ++task) {
    const std::size_t k = task / bands, band = task % bands;
    const std::size_t from = k * np + static_cast<std::size_t>(h) * band / bands * w;
    // Moved down (kept <= from): memmove, since the ranges overlap or coincide.
    if (from != kept) std::memmove(d.data() + kept, d.data() + from, count[task] * sizeof(float));
    kept += count[task];
  }
  d.resize(kept);
  t.samples = d.size();
  if (d.size() < TailModel::kMinSamples) return t;
  t.at1e2 = upperQuantile(d, 1e-2);
  t.at1e3 = upperQuantile(d, 1e-3);
  t.scale = std::max(0.0, (t.at1e3 - t.at1e2) / std::log(10.0));
  return t;
}

double noiseFromFrameDifferences(const FrameCube& cube) {
  const std::size_t nf = cube.frameCount();
  if (nf < 2) return 0.0;
  const auto& mask = cube.mask();
  const std::size_t np = cube.framePixels();
  // Three frame pairs, one per thread; NaN marks a pair without samples.
  std::vector<double> each(3, std::numeric_limits<double>::quiet_NaN());
  parallelFor(each.size(), 1, [&](std::size_t k0, std::size_t k1) {
    for (std::size_t k = k0; k < k1; ++k) {
      const std::size_t a = (nf - 1) * k / 3, b = a + 1;
      std::vector<float> d;
      d.reserve(np);
      for (std::size_t i = 0; i < np; ++i) {
        if (!mask.empty() && (mask[a * np + i] || mask[b * np + i])) continue;
        d.push_back(cube.frame(b)[i] - cube.frame(a)[i]);
      }
      if (d.size() > 1) each[k] = stats::sigmaClipSymmetric(d.data(), d.size(), 5.0).sigma / std::sqrt(2.0);
    }
  });
  std::vector<double> sig;
  for (const double v : each)
    if (!std::isnan(v)) sig.push_back(v);
  if (sig.empty()) return 0.0;
  std::sort(sig.begin(), sig.end());
  return sig[sig.size() / 2];
}

CosmicRayResult removeCosmicRays(FrameCube& cube, const CosmicRayParams& params, ProgressSink& progress,
                                 CancelToken& cancel, const detect::SkyStackCache::Provider* stacks,
                                 const CosmicRayPreTest* preTestProvider) {
  CosmicRayResult out;
  const std::size_t nf = cube.frameCount();
  out.perFrame.assign(nf, 0);
  if (nf < 3) return out;
  PartTimer timer(out.parts);
  out.sigma = noiseFromFrameDifferences(cube);
  timer.lap("noise");
  if (!(out.sigma > 0.0)) return out;
  const Protection prot = protection(cube, params, out.sigma, progress, cancel, stacks);
  timer.lap("protection");
  out.parts.add("protection: its stacks", prot.stackSeconds);
  out.protectedPixels = prot.mask.count();
  out.protectionStacks = prot.stacks;
  out.protectionStacksProvided = prot.provided;
  const TimeReference ref(cube, prot.mask);
  const int w = cube.width(), h = cube.height();
  const std::size_t np = cube.framePixels();
  const auto& mask = cube.mask();
  const float* px = cube.pixels().data();
  out.tail = fitExcessTail(cube, params.skyRate,
                           [&](std::size_t n, int x, int y) { return prot.mask.covers(n, x, y); });
  out.seedThreshold = std::max(params.thresholdSigma * out.sigma, out.tail.threshold(params.falseFlagRate));
  out.growThreshold = std::max(params.growSigma * out.sigma, out.tail.threshold(params.growFalseRate));
  timer.lap("tail");
  // Pixel (x, y) of frame n is a hit when its excess over the registered reference exceeds `thr` and, on a
  // protected star, the star's own signal there (seeing and photon noise make a star pixel vary far more
  // than the sky).
  auto isHit = [&](std::size_t n, int x, int y, float thr) {
    const std::size_t i = static_cast<std::size_t>(y) * w + x;
    if (!mask.empty() && mask[n * np + i]) return false;
    // Cheap exact pre-test: the reference maximum includes the same pixel of the two nearest frames.
    const auto [a, b] = neighbours(n, nf);
    if (px[n * np + i] - std::max(px[a * np + i], px[b * np + i]) <= thr) return false;
    float mx = 0.0f, mean = 0.0f;
    if (!ref.at(n, x, y, &mx, &mean)) return false;
    const float ex = px[n * np + i] - mx;
    if (ex <= thr) return false;
    if (params.saturationLevel) {  // the tip of a bleed column
      const float sat = static_cast<float>(params.bleedFraction * *params.saturationLevel);
      for (int dy = -params.bleedReachPx; dy <= params.bleedReachPx; ++dy) {
        const int qy = y + dy;
        if (dy != 0 && qy >= 0 && qy < h && px[n * np + static_cast<std::size_t>(qy) * w + x] >= sat)
          return false;
      }
    }
    return !prot.mask.covers(n, x, y) || ex > params.protectedExcess * prot.signalAt(n, x, y);
  };
  const float thr = static_cast<float>(out.seedThreshold);
  // The core of a source the PSF resolves (CosmicRayParams::sourceMedianLow): the 3 x 3 median above the
  // 5 x 5 ring's median, against the pixel's own value above it. Masked pixels take no part.
  const bool shapeTest = params.sourceMedianLow > 0.0;
  auto resolvedSource = [&](std::size_t n, int x, int y) {
    if (x < 2 || y < 2 || x >= w - 2 || y >= h - 2) return false;
    const float* f = px + n * np;
    const std::uint8_t* mk = mask.empty() ? nullptr : mask.data() + n * np;
    float inner[9], ring[16];
    int ni = 0, nr = 0;
    for (int dy = -2; dy <= 2; ++dy)
      for (int dx = -2; dx <= 2; ++dx) {
        const std::size_t q = static_cast<std::size_t>(y + dy) * w + (x + dx);
        if (mk && mk[q]) continue;
        if (std::abs(dx) == 2 || std::abs(dy) == 2)
          ring[nr++] = f[q];
        else
          inner[ni++] = f[q];
      }
    if (ni < 9 || nr < 8) return false;
    std::nth_element(ring, ring + nr / 2, ring + nr);
    std::nth_element(inner, inner + 4, inner + 9);
    const double level = ring[nr / 2];
    const double core = f[static_cast<std::size_t>(y) * w + x] - level, med = inner[4] - level;
    return med >= params.sourceMedianSigma * out.sigma && med >= params.sourceMedianLow * core &&
           med <= params.sourceMedianHigh * core;
  };
  std::mutex m;
  std::size_t sourceSeeds = 0;
  // The pre-test of every pixel from a device when it makes it (the same pixels pass).
  std::optional<CosmicRayPreTestWords> preTestWords;
  if (preTestProvider && *preTestProvider) {
    preTestWords = (*preTestProvider)(cube, thr);
    if (preTestWords && (preTestWords->index.size() != preTestWords->bits.size() ||
                         std::adjacent_find(preTestWords->index.begin(), preTestWords->index.end(),
                                            std::greater_equal<>()) != preTestWords->index.end()))
      preTestWords.reset();
    out.preTestProvided = preTestWords.has_value();
  }
  // Pass 1, read-only: seeds.
  parallelFor(nf, 4, [&](std::size_t n0, std::size_t n1) {
    std::vector<std::uint64_t> local;
    std::vector<std::uint32_t> candidates;
    std::size_t sources = 0;
    for (std::size_t n = n0; n < n1; ++n) {
      cancel.throwIfCancelled();
      const auto [a, b] = neighbours(n, nf);
      const float *f = px + n * np, *fa = px + a * np, *fb = px + b * np;
      // The pre-test of isHit, 8 pixels at a time on the AVX2 path (or the device's); the candidates in
      // order.
      candidates.clear();
      if (preTestWords)
        preTestFromWords(*preTestWords, n, np, candidates);
      else
        preTest(f, fa, fb, np, thr, candidates);
      for (const std::uint32_t i : candidates) {
        const int x = static_cast<int>(i % w), y = static_cast<int>(i / w);
        if (!isHit(n, x, y, thr)) continue;
        if (shapeTest && resolvedSource(n, x, y))
          ++sources;
        else
          local.push_back(n * np + i);
      }
    }
    std::lock_guard lock(m);
    sourceSeeds += sources;
    out.pixels.insert(out.pixels.end(), local.begin(), local.end());
    progress.report(0.5 + 0.4 * static_cast<double>(n1) / nf, "cosmic rays");
  });
  out.sourceSeeds = sourceSeeds;
  timer.lap("seeds");
  // Pass 2, read-only: grow by the 8-neighbours above the grow threshold (twice, for short tracks).
  const float grow = static_cast<float>(out.growThreshold);
  std::sort(out.pixels.begin(), out.pixels.end());
  for (int pass = 0; pass < 2; ++pass) {
    std::vector<std::uint64_t> added;
    for (std::uint64_t p : out.pixels) {
      const std::size_t n = p / np, i = p % np;
      const int x = static_cast<int>(i % w), y = static_cast<int>(i / w);
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int qx = x + dx, qy = y + dy;
          if ((dx == 0 && dy == 0) || qx < 0 || qy < 0 || qx >= w || qy >= h) continue;
          if (isHit(n, qx, qy, grow)) added.push_back(n * np + static_cast<std::size_t>(qy) * w + qx);
        }
    }
    out.pixels.insert(out.pixels.end(), added.begin(), added.end());
    std::sort(out.pixels.begin(), out.pixels.end());
    out.pixels.erase(std::unique(out.pixels.begin(), out.pixels.end()), out.pixels.end());
  }
  // Pass 3: fill. Reference values come from frames not yet modified: compute all fills first.
  std::vector<float> fill(out.pixels.size(), 0.0f);
  if (params.fill == CosmicRayParams::Fill::TimeNeighbours) {
    for (std::size_t k = 0; k < out.pixels.size(); ++k) {
      const std::size_t n = out.pixels[k] / np, i = out.pixels[k] % np;
      float mx = 0.0f;
      ref.at(n, static_cast<int>(i % w), static_cast<int>(i / w), &mx, &fill[k]);
    }
  }
  float* wpx = cube.pixels().data();
  for (std::size_t k = 0; k < out.pixels.size(); ++k) {
    wpx[out.pixels[k]] = fill[k];
    ++out.perFrame[out.pixels[k] / np];
  }
  out.total = out.pixels.size();
  timer.lap("growing and filling");
  progress.report(1.0, "cosmic rays");
  return out;
}

void zeroPixels(FrameCube& cube, const std::vector<std::uint64_t>& pixels) {
  float* px = cube.pixels().data();
  for (std::uint64_t p : pixels)
    if (p < cube.pixels().size()) px[p] = 0.0f;
}

}  // namespace st::calib

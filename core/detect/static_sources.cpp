#include "st/detect/static_sources.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <iterator>
#include <map>
#include <memory>
#include <vector>

#include "st/common/parallel.hpp"
#include "st/detect/sky_stack.hpp"
#include "st/stats/sigma_clip.hpp"
#include "source_motion.hpp"
#include "star_footprint.hpp"

namespace st::detect {
namespace {

// Connected pixels (8-neighbours) with grows[i], reached from a pixel with seeds[i].
std::vector<std::vector<int>> components(const std::vector<std::uint8_t>& seeds,
                                         const std::vector<std::uint8_t>& grows, int w, int h) {
  std::vector<std::vector<int>> out;
  std::vector<std::uint8_t> seen(seeds.size(), 0);
  std::vector<int> stack;
  // The seeds are a few thousand of a canvas's 1-2M pixels: memchr skips the zeros many at a time (the
  // byte-by-byte scan took ~3 ms a call on paper-neo's 1500-frame canvas; issue 16). Seeds are 0 or 1.
  const std::uint8_t* const begin = seeds.data();
  const std::uint8_t* const end = begin + seeds.size();
  for (const std::uint8_t* at = begin; at < end; ++at) {
    at = static_cast<const std::uint8_t*>(std::memchr(at, 1, static_cast<std::size_t>(end - at)));
    if (!at) break;
    const int i = static_cast<int>(at - begin);
    if (seen[i]) continue;
    std::vector<int> comp;
    stack.push_back(i);
    seen[i] = 1;
    while (!stack.empty()) {
      const int p = stack.back();
      stack.pop_back();
      comp.push_back(p);
      const int px = p % w, py = p / w;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int qx = px + dx, qy = py + dy;
          if (qx < 0 || qy < 0 || qx >= w || qy >= h) continue;
          const int q = qy * w + qx;
          if (seen[q] || !grows[q]) continue;
          seen[q] = 1;
          stack.push_back(q);
        }
    }
    out.push_back(std::move(comp));
  }
  return out;
}

// Pixels per task of the element-wise loops below (a canvas is ~1M pixels: ~16 tasks).
constexpr std::size_t kPixelChunk = std::size_t{1} << 16;

// value(i) of the pixels i < n with keep(i), in pixel order (the serial loop's vector), on every core.
template <class Keep, class Value>
std::vector<float> gatherInOrder(std::size_t n, const Keep& keep, const Value& value) {
  const std::size_t chunks = (n + kPixelChunk - 1) / kPixelChunk;
  std::vector<std::size_t> start(chunks + 1, 0);
  parallelFor(chunks, 1, [&](std::size_t c0, std::size_t c1) {
    for (std::size_t c = c0; c < c1; ++c) {
      std::size_t kept = 0;
      for (std::size_t i = c * kPixelChunk; i < std::min(n, (c + 1) * kPixelChunk); ++i)
        kept += keep(i) ? 1 : 0;
      start[c + 1] = kept;
    }
  });
  for (std::size_t c = 0; c < chunks; ++c)
    start[c + 1] += start[c];
  std::vector<float> out(start.back());
  parallelFor(chunks, 1, [&](std::size_t c0, std::size_t c1) {
    for (std::size_t c = c0; c < c1; ++c) {
      std::size_t k = start[c];
      for (std::size_t i = c * kPixelChunk; i < std::min(n, (c + 1) * kPixelChunk); ++i)
        if (keep(i)) out[k++] = value(i);
    }
  });
  return out;
}

/// True when, in the frame nearest t_ref, the footprint `comp` (canvas indices of the sky-rate stack `s`,
/// placed in that frame by the stack's own integer shift) has a flat top: >= 5 pixels within 3% of its
/// highest value, far above the background: a full well that bled (the bleed column, in the footprint, is
/// flat too, however far the centroid lies from the core). The stack's per-pixel maximum alone cannot tell:
/// a bright object moving across many frames leaves a plateau there along its track (each pixel it crosses
/// peaks at the same value), while in one frame it is a PSF with at most 4 near-equal pixels.
bool flatTopInFrame(const FrameCube& cube, Velocity skyRate, const std::vector<int>& comp, const SkyStack& s,
                    double background) {
  const std::vector<double> dt = cube.timeOffsetsS();
  if (dt.empty() || comp.empty()) return false;
  std::size_t k = 0;
  for (std::size_t i = 1; i < dt.size(); ++i)
    if (std::abs(dt[i]) < std::abs(dt[k])) k = i;
  const MovingMask geom(cube, skyRate);
  const int w = cube.width(), h = cube.height(), cw = s.mean.width;
  const float* f = cube.frame(k);
  const auto& mask = cube.mask();
  std::vector<float> values;
  values.reserve(comp.size());
  for (int p : comp) {
    const int x = s.x0 + p % cw + geom.shiftX(k), y = s.y0 + p / cw + geom.shiftY(k);
    if (x < 0 || y < 0 || x >= w || y >= h) continue;
    const std::size_t i = static_cast<std::size_t>(y) * w + x;
    if (!mask.empty() && mask[k * cube.framePixels() + i]) continue;
    values.push_back(f[i]);
  }
  if (values.empty()) return false;
  const float top = *std::max_element(values.begin(), values.end());
  if (!(top - background > 1000.0)) return false;
  const auto near = std::count_if(values.begin(), values.end(), [&](float v) { return v >= 0.97f * top; });
  return near >= 5;
}

Star describe(const std::vector<int>& comp, const Image& resid, const std::vector<float>& snr,
              const std::vector<float>& snrF, const SkyStack& s, const StaticSourceParams& params,
              double background, const FrameCube& cube, Velocity skyRate) {
  Star st;
  double sw = 0.0, sx = 0.0, sy = 0.0;
  float peakMax = -1e30f;
  const int w = resid.width;
  for (int p : comp) {
    const double v = resid.pixels[p];
    st.flux += v;
    if (v > st.peak) st.peak = v;
    st.snr = std::max<double>(st.snr, snr[p]);
    st.filteredSnr = std::max<double>(st.filteredSnr, snrF[p]);
    peakMax = std::max(peakMax, s.max.pixels[p]);
    if (v > 0) {
      sw += v;
      sx += v * (p % w);
      sy += v * (p / w);
    }
  }
  st.pixels = static_cast<int>(comp.size());
  st.x = s.x0 + (sw > 0 ? sx / sw : comp.front() % w);
  st.y = s.y0 + (sw > 0 ? sy / sw : comp.front() / w);
  // Saturation: the given level (ADC full scale), or a flat top: >= 5 pixels within 3% of the highest value
  // (the flat spreads a plateau by its pixel-to-pixel rms; an unsaturated star centred on a pixel corner
  // has at most 4 near-equal pixels), far above the background: a full well that bled before the ADC
  // saturated.
  std::map<int, int> satPerColumn;
  int atLevel = 0, nearTop = 0;
  for (int p : comp) {
    const float m = s.max.pixels[p];
    const bool level = params.saturationLevel && m >= *params.saturationLevel;
    const bool flat = m >= 0.97f * peakMax && peakMax - background > 1000.0;
    atLevel += level;
    nearTop += flat;
    if (level || flat) ++satPerColumn[p % w];
  }
  st.saturated = atLevel > 0 || (nearTop >= 5 && flatTopInFrame(cube, skyRate, comp, s, background));
  if (st.saturated) {
    const int run = std::max(3, static_cast<int>(std::ceil(2.0 * params.psfFwhmPx)));
    for (const auto& [col, n] : satPerColumn)
      if (n >= run) st.bleedColumns.push_back(col + s.x0);
  }
  return st;
}

// The stack less its mesh background, its per-pixel SNR and its PSF-filtered SNR. Two passes: the mesh
// background of the stack, then again with the sources of the first pass left out of it (the wings and arms
// of a bright star raise the clipped mean of its cells and hide faint stars next to it).
struct StackSnr {
  Image resid, local;
  std::vector<float> snr, snrF;
  stats::ClipStats noise;
};

// One pass's mesh background of s.mean with `weight`, the residual, its clipped noise (of R sqrt(count),
// the single-frame noise scale everywhere) and the per-pixel SNR into `a` (a.snr left as it is where the
// noise is 0; a.snrF not touched).
void meshPass(const SkyStack& s, const Image& weight, int meshPx, StackSnr& a, PartTimer& timer,
              CancelToken& cancel) {
  a.local = meshBackground(s.mean, weight, meshPx);
  timer.lap("analysis: mesh background");
  a.resid = residualWhereCounted(s.mean, s.count, a.local);
  const std::size_t np = a.resid.size();
  const std::vector<float> scaled = gatherInOrder(
      np, [&](std::size_t i) { return s.count.pixels[i] > 0; },
      [&](std::size_t i) { return a.resid.pixels[i] * std::sqrt(s.count.pixels[i]); });
  timer.lap("analysis: residual");
  a.noise = stats::sigmaClipSymmetric(scaled.data(), scaled.size(), 4.0);
  timer.lap("analysis: noise clip");
  if (a.noise.sigma > 0) {
    parallelFor(np, kPixelChunk, [&](std::size_t i0, std::size_t i1) {
      for (std::size_t i = i0; i < i1; ++i)
        a.snr[i] = static_cast<float>(a.resid.pixels[i] * std::sqrt(s.count.pixels[i]) / a.noise.sigma);
    });
  }
  cancel.throwIfCancelled();
  timer.lap("analysis: SNR");
}

// What `cache` keeps of `kind` for this cube, rate, level and mesh (SkyStackCache::derived), else made by
// `make` and kept there for the next search.
template <class T, class Make>
std::shared_ptr<const T> keptOrMade(SkyStackCache& cache, SkyStackCache::Derived kind, const FrameCube& cube,
                                    Velocity rate, double background, int meshPx, Make&& make) {
  auto kept = std::static_pointer_cast<const T>(cache.derived(kind, cube, rate, background, meshPx));
  if (!kept) {
    kept = std::make_shared<const T>(make());
    cache.keepDerived(kind, cube, rate, background, meshPx, kept);
  }
  return kept;
}

// The first pass up to its per-pixel SNR (snrF empty): no FWHM in it, so kept in the cache for the next
// search of the same stack (SkyStackCache::Derived::FirstAnalysis).
StackSnr firstAnalysis(const SkyStack& s, int meshPx, TimedParts& parts, CancelToken& cancel) {
  PartTimer timer(parts);
  StackSnr f;
  f.snr.assign(s.mean.size(), 0.0f);
  meshPass(s, s.count, meshPx, f, timer, cancel);
  return f;
}

// The rest of the two passes from `first` (firstAnalysis).
StackSnr analyseStack(const SkyStack& s, const StackSnr& first, const StaticSourceParams& params,
                      CancelToken& cancel, const SkyStackCache::SnrProvider* device, TimedParts& parts) {
  PartTimer timer(parts);
  const std::size_t np = s.mean.size();
  // What the velocity search sees at the sky rate: faint stars below the threshold per pixel are above it
  // after the matched filter.
  std::vector<float> firstSnrF(np, 0.0f);
  if (params.filteredDetection)
    firstSnrF = detail::filteredSnr(first.resid, s.count, first.noise.sigma, params.psfFwhmPx, device);
  timer.lap("analysis: filtered SNR");
  const Image weight = detail::excludeSources(s.count, first.snr, firstSnrF, params.growSnr + 1.0,
                                              static_cast<int>(std::ceil(params.psfFwhmPx)));
  timer.lap("analysis: sources left out");
  StackSnr a;
  a.snr = first.snr;  // kept where the second pass's noise is 0
  meshPass(s, weight, params.meshPx, a, timer, cancel);
  a.snrF.assign(np, 0.0f);
  if (params.filteredDetection)
    a.snrF = detail::filteredSnr(a.resid, s.count, a.noise.sigma, params.psfFwhmPx, device);
  timer.lap("analysis: filtered SNR");
  return a;
}

// Sources seen per pixel (the first nPerPixel components) that are not saturated, however bright (a bright
// slow mover is above spikeSnr in the stack): their centroids in the stacks of the thirds of the frames and
// the stars' common shift (keepMovers).
struct Motion {
  std::shared_ptr<const detail::ThirdStacks> thirds;  // null where movers are not judged
  std::vector<detail::SourceShift> shifts;
  std::pair<double, double> common{0.0, 0.0};
};

Motion measureMotions(const FrameCube& cube, Velocity skyRate, double background,
                      const std::vector<std::vector<int>>& comps, std::size_t nPerPixel,
                      const std::vector<Star>& stars, int cw, double sigma, const StaticSourceParams& params,
                      SkyStackCache& stacks, CancelToken& cancel) {
  Motion m;
  m.shifts.resize(nPerPixel);
  if (!params.keepMovers) return m;
  // Kept in `stacks` for the next search of the same cube (the PSF's catalogue, then the search at the fitted
  // FWHM): the same images.
  m.thirds = keptOrMade<detail::ThirdStacks>(
      stacks, SkyStackCache::Derived::Thirds, cube, skyRate, background, params.meshPx,
      [&] { return detail::thirdStacks(cube, skyRate, background, params.meshPx, stacks, cancel); });
  if (!m.thirds->valid()) return m;
  parallelFor(nPerPixel, 4, [&](std::size_t k0, std::size_t k1) {
    for (std::size_t k = k0; k < k1; ++k)
      if (!stars[k].saturated) m.shifts[k] = detail::measureShift(comps[k], cw, *m.thirds, sigma);
  });
  m.common = detail::commonShift(m.shifts);
  return m;
}

// Judges component k (seen per pixel) and, when it moves, records it in out.movers and out.moverMask.
bool keptAsMover(const Motion& motion, std::size_t k, const std::vector<int>& comp, const SkyStack& s, int cw,
                 Velocity skyRate, const StaticSourceParams& params, Star& star, StaticSources& out) {
  if (k >= motion.shifts.size() || !motion.shifts[k].measured) return false;
  MovingSource m =
      detail::judgeMotion(motion.shifts[k], motion.common, *motion.thirds, s.x0, s.y0, params, star);
  if (!m.moving) return false;
  // A bright source must also leave its earlier place (a saturated star's changing bleed moves its centroid).
  if (star.snr >= params.spikeSnr && !detail::vacates(comp, cw, *motion.thirds, params.psfFwhmPx))
    return false;
  m.v = {m.v.vx + skyRate.vx, m.v.vy + skyRate.vy};
  for (int p : comp)
    out.moverMask.set(s.x0 + p % cw, s.y0 + p / cw);
  out.movers.push_back(m);
  return true;
}

}  // namespace

StaticSources findStaticSources(const FrameCube& cube, Velocity skyRate, double background,
                                const StaticSourceParams& given, ProgressSink& progress, CancelToken& cancel,
                                SkyStackCache* stacks) {
  StaticSourceParams params = given;
  if (params.catalogueOnly) params.filteredDetection = false;
  SkyStackCache own;
  SkyStackCache& cache = stacks ? *stacks : own;
  StaticSources out;
  PartTimer timer(out.parts);
  auto lap = [&timer](const char* part) { timer.lap(part); };
  out.mask = MovingMask(cube, skyRate);
  out.moverMask = out.mask;
  SubProgress sub(progress, 0.0, 0.8);
  const SkyStack& s = cache.stack(cube, skyRate, background, sub, cancel);
  // The stacks of the thirds (the movers' test) made beside the analysis below where a provider (a device)
  // makes them, and those of the halves (the faint sources' test) once there is a source to test: the same
  // stacks, off this thread's path (issue 16).
  if (params.keepMovers) cache.prefetch(cube, skyRate, background, detail::thirdRanges(cube.frameCount()));
  lap("stack");
  const int cw = s.mean.width, ch = s.mean.height;
  TimedParts analysisParts;
  const auto first = keptOrMade<StackSnr>(
      cache, SkyStackCache::Derived::FirstAnalysis, cube, skyRate, background, params.meshPx,
      [&] { return firstAnalysis(s, params.meshPx, analysisParts, cancel); });
  const StackSnr an = analyseStack(s, *first, params, cancel, cache.snrProvider(), analysisParts);
  lap("analysis");
  out.parts.add(analysisParts);
  const Image& resid = an.resid;
  const std::vector<float>& snr = an.snr;
  const std::vector<float>& snrF = an.snrF;
  const stats::ClipStats& noise = an.noise;
  const Image& local = an.local;
  out.stackNoise = noise.sigma;
  // Stars of the stack itself (SNR >= threshold per pixel, grown to growSnr), then sources seen only after
  // the filter (SNR >= weakSnr there, grown over the filtered blob, outside the first ones: the filtered
  // blobs of neighbouring stars merge, the per-pixel footprints do not).
  std::vector<std::uint8_t> seeds(resid.size()), grows(resid.size()), taken(resid.size(), 0);
  parallelFor(resid.size(), kPixelChunk, [&](std::size_t i0, std::size_t i1) {
    for (std::size_t i = i0; i < i1; ++i) {
      seeds[i] = snr[i] >= params.snrThreshold;
      grows[i] = snr[i] >= params.growSnr;
    }
  });
  auto comps = components(seeds, grows, cw, ch);
  const std::size_t nPerPixel = comps.size();
  if (params.filteredDetection) {
    // The filtered blob of a star reaches a kernel radius beyond its per-pixel footprint: not a new source.
    // By bands of rows on every core: a band paints the discs of the pixels within r rows of it (listed by
    // row), in its own rows only.
    const int r = static_cast<int>(std::ceil(1.5 * params.psfFwhmPx)) + 1;
    std::vector<std::vector<int>> byRow(static_cast<std::size_t>(ch));
    for (const auto& comp : comps)
      for (int p : comp)
        byRow[static_cast<std::size_t>(p / cw)].push_back(p % cw);
    constexpr int kBandRows = 16;
    parallelFor(static_cast<std::size_t>((ch + kBandRows - 1) / kBandRows), 1,
                [&](std::size_t b0, std::size_t b1) {
                  for (std::size_t b = b0; b < b1; ++b) {
                    const int y0 = static_cast<int>(b) * kBandRows, y1 = std::min(ch, y0 + kBandRows);
                    for (int py = std::max(0, y0 - r); py < std::min(ch, y1 + r); ++py)
                      for (int px : byRow[static_cast<std::size_t>(py)])
                        for (int y = std::max(y0, py - r); y < std::min(y1, py + r + 1); ++y)
                          for (int dx = -r; dx <= r; ++dx) {
                            const int x = px + dx, dy = y - py;
                            if (x >= 0 && x < cw && dx * dx + dy * dy <= r * r)
                              taken[static_cast<std::size_t>(y) * cw + x] = 1;
                          }
                  }
                });
    parallelFor(resid.size(), kPixelChunk, [&](std::size_t i0, std::size_t i1) {
      for (std::size_t i = i0; i < i1; ++i) {
        grows[i] = !taken[i] && snrF[i] >= params.weakSnr;
        seeds[i] = grows[i];
      }
    });
    auto more = components(seeds, grows, cw, ch);
    comps.insert(comps.end(), std::make_move_iterator(more.begin()), std::make_move_iterator(more.end()));
    // Sources seen only after the filter are tested on the halves' stacks below: made ahead, beside the
    // describing and the motions (issue 16).
    if (comps.size() > nPerPixel)
      cache.prefetch(cube, skyRate, background, detail::halfRanges(cube.frameCount()));
  }
  lap("components");
  double frames = 0.0;
  for (float c : s.count.pixels)
    frames = std::max<double>(frames, c);
  const int base = static_cast<int>(std::ceil(params.dilateFwhm * params.psfFwhmPx)) + 1;
  // Where the star field does not drift over the span (a guided, sidereally tracked sequence) the per-pixel
  // background removes each star's light as far as it is constant: what is left to mask is where single
  // frames see the star (its photon noise, seeing and guiding residuals), not where a stack would. A drifting
  // field crosses the pixels, so there every star is masked down to one stack sigma.
  // Registered frames with per-frame offsets (dithers, re-pointing): the stars move across the detector by
  // the offsets' spread, so the field is not static there even at a zero sky rate, unless they are the
  // sub-pixel remainders left by registration's whole-pixel alignment (detect::alignWholePixels).
  double offsetSpread = 0.0;
  if (cube.hasFrameOffsets()) {
    double lo[2] = {0.0, 0.0}, hi[2] = {0.0, 0.0};
    for (const FrameInfo& fi : cube.info()) {
      lo[0] = std::min(lo[0], fi.offsetXPx), hi[0] = std::max(hi[0], fi.offsetXPx);
      lo[1] = std::min(lo[1], fi.offsetYPx), hi[1] = std::max(hi[1], fi.offsetYPx);
    }
    offsetSpread = std::hypot(hi[0] - lo[0], hi[1] - lo[1]);
  }
  const bool staticField =
      offsetSpread + std::hypot(skyRate.vx, skyRate.vy) * cube.timeSpanS() < params.psfFwhmPx;
  // A drifting field whose stars are subtracted afterwards (subtractStarTemplate over the wide footprints
  // kept in subtractRegion) is masked like a static one, where single frames see the stars.
  const bool subtracted = !staticField && params.subtractStars;
  const bool narrow = staticField || subtracted;
  const double maskFrames = narrow ? 1.0 : frames;
  const double maskSnr = narrow ? params.growSnr * std::sqrt(frames) : 0.0;
  if (subtracted) out.subtractRegion = out.mask;
  const int armHalf = static_cast<int>(std::ceil(0.5 * params.psfFwhmPx));
  std::vector<Star> described(comps.size());
  parallelFor(comps.size(), 4, [&](std::size_t k0, std::size_t k1) {
    for (std::size_t k = k0; k < k1; ++k)
      described[k] = describe(comps[k], resid, snr, snrF, s, params, background, cube, skyRate);
  });
  lap("describing");
  const Motion motion = measureMotions(cube, skyRate, background, comps, nPerPixel, described, cw,
                                       noise.sigma, params, cache, cancel);
  lap("motions");
  detail::HalfStacks halves;
  for (std::size_t k = 0; k < comps.size(); ++k) {
    const auto& comp = comps[k];
    Star st = std::move(described[k]);
    // Seen only after the filter: a static source only if it stays put between the stacks of the first and
    // second halves of the frames (a slow moving object is a streak there, and its halves shift).
    if (k >= nPerPixel) {
      if (halves.empty()) {
        lap("footprints");
        halves = detail::halfStacks(cube, skyRate, background, local, noise.sigma, params.psfFwhmPx, cache,
                                    cancel);
        lap("halves' stacks and SNR");
      }
      int peak = comp.front();
      for (int p : comp)
        if (snrF[p] > snrF[peak]) peak = p;
      if (!halves.isStatic(peak, cw, static_cast<int>(std::ceil(params.psfFwhmPx)) + 1,
                           params.maxHalfShiftPx)) {
        // (Subtracting these too removed a pair of faint stars searched at the sky rate on paper-neo seed 34,
        // but took a mover's pixels where its template was missing: test_pipeline_residuals. Left out.)
        continue;
      }
    } else if (keptAsMover(motion, k, comp, s, cw, skyRate, params, st, out)) {
      continue;
    }
    if (params.catalogueOnly) {
      out.stars.push_back(std::move(st));
      continue;
    }
    for (int p : comp) {
      // A saturated star in a drifting field is masked whole; where single frames are the measure (a static
      // field, or stars subtracted), its clipped core is far above maskSnr anyway.
      if (snr[p] >= maskSnr || (st.saturated && !narrow)) out.mask.set(s.x0 + p % cw, s.y0 + p / cw);
      if (subtracted) out.subtractRegion.set(s.x0 + p % cw, s.y0 + p / cw);
    }
    // The Moffat wings down to one stack sigma per pixel (two of one frame's sigma in a static field, where
    // only the wing's seeing and guiding residual, a fraction of it, is left; the radius grows with the
    // flux).
    if (params.maskWings) {
      // A star that single frames cannot see has no wing radius. In a static field its centre is masked
      // all the same (one pixel, dilated below): the per-pixel background leaves its seeing residuals there,
      // and on the Lowell frames leaving them found a slow SNR 9 candidate at one. Where the stars are
      // subtracted, the template removes such a star and nothing is masked: a 5-pixel cross at every faint
      // star had cost paper-neo seed 24's asteroid, which passes 1 px from a V = 22.5 star, 5.6% of its
      // track.
      const double wing = detail::wingRadiusPx(st.flux, params.psfFwhmPx, params.wingBeta, maskFrames,
                                               narrow ? 2.0 * noise.sigma : noise.sigma);
      if (wing > 0.0)
        detail::setDisc(out.mask, st.x, st.y, wing);
      else if (!subtracted)
        out.mask.set(static_cast<int>(std::lround(st.x)), static_cast<int>(std::lround(st.y)));
      if (subtracted)
        detail::setDisc(
            out.subtractRegion, st.x, st.y,
            detail::wingRadiusPx(st.flux, params.psfFwhmPx, params.wingBeta, frames, noise.sigma));
    }
    // Diffraction spikes along the detector axes and the column bleed of saturated (or very bright) stars.
    if (st.saturated || st.snr >= params.spikeSnr) {
      // Followed in the stack with only the global background removed: the mesh background is raised by
      // the wings of such a star and would cut the arms short.
      // Where the stars are subtracted, so are the spikes (static on the sky like the star): the parts that
      // single frames see are masked with the core (maskSnr), the template removes the rest, and the excess
      // test whitens or masks what is left. Masking them whole cost paper-neo seed 28's asteroid, whose
      // track runs along a saturated star's spike for half the span, 30% of its PSF^2-weighted track.
      // The bleed stays masked: clipped pixels carry nothing.
      detail::maskSpikes(subtracted ? out.subtractRegion : out.mask, s.mean, s.count, noise.sigma, s.x0, s.y0,
                         st, 0, armHalf);
      detail::maskBleed(out.mask, s.mean, s.count, noise.sigma, s.x0, s.y0, st, armHalf);
    }
    out.stars.push_back(std::move(st));
  }
  lap("footprints");
  // The dilation covers the stars' sub-pixel motion under the sky rate's integer shifts; a static field has
  // none, so one pixel there.
  if (!params.catalogueOnly) {
    out.mask.dilate(narrow ? 1 : base);
    out.subtractRegion.dilate(base);
    out.moverMask.dilate(base);
  }
  std::sort(out.stars.begin(), out.stars.end(), [](const Star& a, const Star& b) { return a.flux > b.flux; });
  lap("dilation");
  cache.settle();  // a stack made beside and not asked for (no faint source to test) is kept
  progress.report(1.0, "static sources");
  return out;
}

void prefetchStaticSourceStacks(const FrameCube& cube, Velocity skyRate, double background,
                                const StaticSourceParams& params, SkyStackCache& stacks) {
  std::vector<SkyStackCache::Range> ranges;
  if (params.keepMovers) ranges = detail::thirdRanges(cube.frameCount());
  if (params.filteredDetection && !params.catalogueOnly)
    for (const auto& r : detail::halfRanges(cube.frameCount()))
      ranges.push_back(r);
  if (!ranges.empty()) stacks.prefetch(cube, skyRate, background, ranges);
}

}  // namespace st::detect

#include "sky_rate_chain.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <optional>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#endif

#include <Eigen/Dense>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "sky_rate_links.hpp"
#include "st/common/parallel.hpp"

namespace st::detect::detail {
namespace {

// A stack pixel is used when at least this fraction of its block's frames contributed to it (masked
// samples, a hot pixel or a cosmic ray, may be missing).
constexpr double kFullCoverage = 0.97;

struct Layout {
  std::vector<std::size_t> first;  // block k is frames [first[k], first[k + 1])
  [[nodiscard]] std::size_t count() const { return first.size() - 1; }
};

// Enough contiguous blocks that the stars move at most stepFraction of the frame between neighbours.
Layout layoutBlocks(const FrameCube& cube, Velocity rate, const SkyRateParams& p) {
  const std::size_t nf = cube.frameCount();
  const double span = cube.timeSpanS();
  const double f = std::max(1e-3, p.chainStepFraction);
  const double need = std::max({static_cast<double>(p.chainMinBlocks),
                                std::ceil(std::fabs(rate.vx) * span / (f * cube.width())),
                                std::ceil(std::fabs(rate.vy) * span / (f * cube.height()))});
  const std::size_t most = nf / static_cast<std::size_t>(std::max(1, p.chainMinBlockFrames));
  const std::size_t k = std::min<std::size_t>(most, static_cast<std::size_t>(std::min(need, 1e6)));
  Layout l;
  if (k < 2) return l;
  for (std::size_t b = 0; b <= k; ++b)
    l.first.push_back(nf * b / k);
  return l;
}

// sum[x] += f[x] - background and cnt[x] += 1 where m[x] is not set (m may be null). The AVX2 path adds
// +0.0 where masked, which leaves both as they are: the scalar loop's values exactly.
void addRowScalar(double* sum, double* cnt, const float* f, const std::uint8_t* m, int x0, int n,
                  double background) {
  for (int x = x0; x < n; ++x) {
    if (m && m[x]) continue;
    sum[x] += f[x] - background;
    cnt[x] += 1.0;
  }
}

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define ST_SKY_RATE_CHAIN_AVX2 1
__attribute__((target("avx2"))) int addRowAvx2(double* sum, double* cnt, const float* f,
                                               const std::uint8_t* m, int n, double background) {
  const __m256d bg = _mm256_set1_pd(background), one = _mm256_set1_pd(1.0);
  const __m256i zero = _mm256_setzero_si256();
  int x = 0;
  for (; x + 4 <= n; x += 4) {
    __m256d in = _mm256_castsi256_pd(_mm256_set1_epi64x(-1));
    if (m) {
      std::int32_t m4;
      std::memcpy(&m4, m + x, sizeof m4);
      in = _mm256_castsi256_pd(_mm256_cmpeq_epi64(_mm256_cvtepu8_epi64(_mm_cvtsi32_si128(m4)), zero));
    }
    const __m256d d = _mm256_sub_pd(_mm256_cvtps_pd(_mm_loadu_ps(f + x)), bg);
    _mm256_storeu_pd(sum + x, _mm256_add_pd(_mm256_loadu_pd(sum + x), _mm256_and_pd(d, in)));
    _mm256_storeu_pd(cnt + x, _mm256_add_pd(_mm256_loadu_pd(cnt + x), _mm256_and_pd(one, in)));
  }
  return x;
}
#endif

void addRow(double* sum, double* cnt, const float* f, const std::uint8_t* m, int n, double background) {
  int x0 = 0;
#ifdef ST_SKY_RATE_CHAIN_AVX2
  static const bool avx2 = __builtin_cpu_supports("avx2") != 0;
  if (avx2) x0 = addRowAvx2(sum, cnt, f, m, n, background);
#endif
  addRowScalar(sum, cnt, f, m, x0, n, background);
}

// Block [first, last)'s shifts at `rate` about its own mean time: frame n's stack pixel (x, y) takes frame
// pixel (x + sx, y + sy); its mean time and mean shift into `b`.
ShiftedBlock blockShifts(std::size_t first, std::size_t last, Velocity rate, const std::vector<double>& dt,
                         BlockStack& b) {
  ShiftedBlock s;
  s.first = first;
  s.last = last;
  for (std::size_t n = first; n < last; ++n)
    b.tS += dt[n];
  b.tS /= static_cast<double>(last - first);
  for (std::size_t n = first; n < last; ++n) {
    const int sx = static_cast<int>(std::lround(rate.vx * (dt[n] - b.tS)));
    const int sy = static_cast<int>(std::lround(rate.vy * (dt[n] - b.tS)));
    b.meanShift.x += sx, b.meanShift.y += sy;
    s.sx.push_back(sx);
    s.sy.push_back(sy);
  }
  b.meanShift *= 1.0 / static_cast<double>(last - first);
  return s;
}

}  // namespace

// shiftedSums of one block into rows [y0, y1) of sum and cnt (frame-sized, zeroed there). Each pixel takes
// the block's frames in order, whatever the rows: bands of rows made apart are the whole frame's sums.
void addShifted(const FrameCube& cube, const ShiftedBlock& blk, double background, double* sum, double* cnt,
                int y0, int y1) {
  const int w = cube.width(), h = cube.height();
  const auto& mask = cube.mask();
  const std::size_t np = cube.framePixels();
  for (std::size_t n = blk.first; n < blk.last; ++n) {
    const int sx = blk.sx[n - blk.first], sy = blk.sy[n - blk.first];
    const float* f = cube.frame(n);
    // Stack pixel (x, y) takes frame pixel (x + sx, y + sy).
    for (int y = std::max({0, -sy, y0}); y < std::min({h, h - sy, y1}); ++y) {
      double* srow = sum + static_cast<std::size_t>(y) * w;
      double* crow = cnt + static_cast<std::size_t>(y) * w;
      const std::size_t row = static_cast<std::size_t>(y + sy) * w;
      const int x0 = std::max(0, -sx), x1 = std::min(w, w - sx);
      const std::size_t i0 = row + static_cast<std::size_t>(x0 + sx);
      addRow(srow + x0, crow + x0, f + i0, mask.empty() ? nullptr : mask.data() + n * np + i0, x1 - x0,
             background);
    }
  }
}

namespace {

// The block's stack from its sums: only where (nearly) every frame of the block contributed: where only the
// frames of one end of the block do, a star sits at their mean residual of the whole-pixel shifts, not the
// block's (up to 0.5 px off: at 16.4 px/s and 16.7 Hz the residual ramps through a pixel over ~50 frames).
void finishBlock(BlockStack& b, const ShiftedBlock& blk, const ShiftedSums& sums, int w, int h,
                 double sigma) {
  b.value = cv::Mat::zeros(h, w, CV_32F);
  b.noise = cv::Mat::zeros(h, w, CV_32F);
  b.covered = cv::Mat::zeros(h, w, CV_8U);
  const double full = kFullCoverage * static_cast<double>(blk.last - blk.first);
  // mean(i) and count(i) of pixel i: from the sums, or the device's means and counts (the same values).
  auto fill = [&](const auto& mean, const auto& count) {
    for (int y = 0; y < h; ++y) {
      float* v = b.value.ptr<float>(y);
      float* n = b.noise.ptr<float>(y);
      unsigned char* cov = b.covered.ptr<unsigned char>(y);
      for (int x = 0; x < w; ++x) {
        const std::size_t i = static_cast<std::size_t>(y) * w + x;
        const double c = count(i);
        if (c <= 0 || c < full) continue;
        cov[x] = 255;
        v[x] = mean(i);
        n[x] = static_cast<float>(sigma / std::sqrt(c));
      }
    }
  };
  if (sums.sum.empty())
    fill([&](std::size_t i) { return sums.mean[i]; }, [&](std::size_t i) { return double{sums.frames[i]}; });
  else
    fill([&](std::size_t i) { return static_cast<float>(sums.sum[i] / sums.count[i]); },
         [&](std::size_t i) { return sums.count[i]; });
}

// The blocks' stacks at `rate` into `stacks`, their frames' shifts into `shifts`. A block whose frames keep
// the shifts they had in the previous iteration (`shifts` and `stacks` as that one left them) keeps its
// stack, the same sums of the same frames, and `same` says so; the others' sums come from `provider` when it
// makes them, else from the CPU (in parallel over the blocks).
void stackBlocks(const FrameCube& cube, const Layout& layout, Velocity rate, double background, double sigma,
                 const std::vector<double>& dt, const ShiftedSumsProvider* provider, bool keep,
                 CancelToken& cancel, std::vector<ShiftedBlock>& shifts, std::vector<BlockStack>& stacks,
                 std::vector<char>& same, TimedParts& parts) {
  PartTimer timer(parts);
  const std::size_t k = layout.count();
  const int w = cube.width(), h = cube.height();
  const bool before = keep && shifts.size() == k && stacks.size() == k;
  std::vector<BlockStack> next(k);
  std::vector<ShiftedBlock> nextShifts(k);
  std::vector<std::size_t> todo;
  same.assign(k, 0);
  for (std::size_t b = 0; b < k; ++b) {
    nextShifts[b] = blockShifts(layout.first[b], layout.first[b + 1], rate, dt, next[b]);
    if (before && nextShifts[b].sx == shifts[b].sx && nextShifts[b].sy == shifts[b].sy) {
      next[b] = std::move(stacks[b]);
      same[b] = 1;
    } else {
      todo.push_back(b);
    }
  }
  stacks = std::move(next);
  shifts = std::move(nextShifts);
  if (todo.empty()) return;
  std::vector<ShiftedBlock> blocks;
  for (std::size_t b : todo)
    blocks.push_back(shifts[b]);
  const std::size_t n = todo.size();
  std::optional<std::vector<ShiftedSums>> made;
  if (provider && *provider) {
    made = (*provider)(cube, blocks, background, ShiftedSumsForm::SumsOrMeans);
    // Each block's sums and counts, or its means and counts, of the frame's size; else the CPU's.
    const std::size_t np = cube.framePixels();
    auto whole = [np](const ShiftedSums& b) {
      return (b.sum.size() == np && b.count.size() == np) || (b.mean.size() == np && b.frames.size() == np);
    };
    if (made && (made->size() != n || !std::all_of(made->begin(), made->end(), whole))) made.reset();
  }
  if (made) {
    timer.lap("stacks: sums made elsewhere");
    parallelFor(n, 1, [&](std::size_t q0, std::size_t q1) {
      for (std::size_t q = q0; q < q1; ++q)
        finishBlock(stacks[todo[q]], blocks[q], (*made)[q], w, h, sigma);
    });
    timer.lap("stacks: finished");
    return;
  }
  // On the CPU, as many blocks at a time as there are threads (each block's sums are two frame-sized double
  // images), each group's sums made by bands of rows on every thread.
  const std::size_t group = std::max<unsigned>(1, workerCount());
  for (std::size_t g0 = 0; g0 < n; g0 += group) {
    cancel.throwIfCancelled();
    const std::size_t g1 = std::min(n, g0 + group);
    const std::vector<ShiftedBlock> some(blocks.begin() + static_cast<std::ptrdiff_t>(g0),
                                         blocks.begin() + static_cast<std::ptrdiff_t>(g1));
    const std::vector<ShiftedSums> sums = detect::shiftedSums(cube, some, background);
    parallelFor(g1 - g0, 1, [&](std::size_t q0, std::size_t q1) {
      for (std::size_t q = q0; q < q1; ++q)
        finishBlock(stacks[todo[g0 + q]], blocks[g0 + q], sums[q], w, h, sigma);
    });
  }
}

// Weighted least-squares positions of the star field per block (block 0 at 0) from the links, then a
// straight line through them: the rate, and each block's departure from the line.
void solve(const std::vector<Link>& links, std::vector<SkyRateBlock>& blocks, Velocity* rate) {
  const std::size_t k = blocks.size();
  std::vector<double> pos[2];
  for (int axis = 0; axis < 2; ++axis) {
    Eigen::MatrixXd a = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(links.size()), k - 1);
    Eigen::VectorXd rhs(static_cast<Eigen::Index>(links.size()));
    for (std::size_t l = 0; l < links.size(); ++l) {
      const auto row = static_cast<Eigen::Index>(l);
      const double w = 1.0 / std::sqrt(axis == 0 ? links[l].var.x : links[l].var.y);
      if (links[l].j > 0) a(row, static_cast<Eigen::Index>(links[l].j - 1)) += w;
      if (links[l].i > 0) a(row, static_cast<Eigen::Index>(links[l].i - 1)) -= w;
      rhs(row) = w * (axis == 0 ? links[l].d.x : links[l].d.y);
    }
    const Eigen::VectorXd p = a.colPivHouseholderQr().solve(rhs);
    pos[axis].assign(k, 0.0);
    for (std::size_t b = 1; b < k; ++b)
      pos[axis][b] = p(static_cast<Eigen::Index>(b - 1));
  }
  const std::vector<double>&px = pos[0], &py = pos[1];
  double mt = 0.0, mx = 0.0, my = 0.0;
  for (std::size_t b = 0; b < k; ++b)
    mt += blocks[b].tS / k, mx += px[b] / k, my += py[b] / k;
  double stt = 0.0, stx = 0.0, sty = 0.0;
  for (std::size_t b = 0; b < k; ++b) {
    const double t = blocks[b].tS - mt;
    stt += t * t, stx += t * (px[b] - mx), sty += t * (py[b] - my);
  }
  *rate = {stx / stt, sty / stt};
  for (std::size_t b = 0; b < k; ++b) {
    const double t = blocks[b].tS - mt;
    blocks[b].offsetPx = {px[b] - mx - rate->vx * t, py[b] - my - rate->vy * t};
  }
}

// True when every frame keeps its whole-pixel shift within its block at rate `b` as at rate `a`: the
// stacks, hence the measurement, would not change.
bool sameShifts(const Layout& l, const std::vector<SkyRateBlock>& blocks, const std::vector<double>& dt,
                Velocity a, Velocity b) {
  for (std::size_t k = 0; k < l.count(); ++k)
    for (std::size_t n = l.first[k]; n < l.first[k + 1]; ++n) {
      const double t = dt[n] - blocks[k].tS;
      if (std::lround(a.vx * t) != std::lround(b.vx * t) || std::lround(a.vy * t) != std::lround(b.vy * t))
        return false;
    }
  return true;
}

}  // namespace

ChainResult chainSkyRate(const FrameCube& cube, Velocity start, double background, double sigma,
                         const SkyRateParams& params, CancelToken& cancel, const ShiftedSumsProvider* sums,
                         const PhaseCorrelationProvider* correlate) {
  ChainResult out;
  const Layout layout = layoutBlocks(cube, start, params);
  if (layout.first.size() < 3) {
    out.why = "too few frames for two blocks of " + std::to_string(params.chainMinBlockFrames);
    return out;
  }
  const std::size_t k = layout.count();
  const auto dt = cube.timeOffsetsS();
  cv::Mat window;
  cv::createHanningWindow(window, cv::Size(cube.width(), cube.height()), CV_64F);
  Velocity rate = start;
  TimedParts threadTime, stackParts;
  PartTimer timer(out.parts);
  std::vector<ShiftedBlock> shifts;
  std::vector<BlockStack> stacks;
  std::vector<char> same;
  TriedLinks tried;
  // The first iteration by neighbouring blocks only, when asked: its rate only sets the next one's stacks.
  // Where the neighbours do not link every block, every pair is linked in it (the neighbours' links kept).
  bool coarse = params.chainCoarseFirst && k > 2;
  for (int it = 0, full = 0; full < 4; ++it) {
    stackBlocks(cube, layout, rate, background, sigma, dt, sums, params.chainKeepUnchanged, cancel, shifts,
                stacks, same, stackParts);
    timer.lap("stacks");
    out.stacksKept += static_cast<int>(std::count(same.begin(), same.end(), 1));
    std::vector<Link> links = measureLinks(stacks, rate, window, params, cube.width(), cube.height(), cancel,
                                           correlate, &threadTime, same, tried, &out.linksKept, coarse);
    if (coarse && !connected(k, links)) {
      coarse = false;
      const std::vector<char> kept(k, 1);
      int keptWithinIteration =
          0;  // the neighbours' links, re-used in this iteration: not "kept from the one before"
      links = measureLinks(stacks, rate, window, params, cube.width(), cube.height(), cancel, correlate,
                           &threadTime, kept, tried, &keptWithinIteration);
    }
    timer.lap("links");
    out.iterations = it + 1;
    if (!connected(k, links)) {
      // A later iteration that loses the chain keeps the earlier one's result; after a coarse first one,
      // which leaves none, the chain is measured again without it (what it would have kept).
      if (!out.ok && out.coarseFirst) {
        SkyRateParams again = params;
        again.chainCoarseFirst = false;
        ChainResult redo = chainSkyRate(cube, start, background, sigma, again, cancel, sums, correlate);
        redo.parts.add(out.parts);  // the time spent here too
        return redo;
      }
      if (!out.ok)
        out.why = "the " + std::to_string(k) + " blocks could not all be linked by shared stars (" +
                  std::to_string(links.size()) + " links)";
      break;
    }
    std::vector<SkyRateBlock> blocks(k);
    for (std::size_t b = 0; b < k; ++b)
      blocks[b] = {layout.first[b], layout.first[b + 1], stacks[b].tS, {}};
    Velocity next;
    solve(links, blocks, &next);
    if (coarse) {  // the next iteration's rate, not a result
      coarse = false;
      out.coarseFirst = true;
      // Where it keeps every frame's shifts, the next iteration links every pair at this rate, as one
      // without a coarse first would (the stacks and the neighbours' links kept: no extra cost).
      if (!sameShifts(layout, blocks, dt, rate, next)) rate = next;
      continue;
    }
    ++full;
    std::vector<double> responses;
    int starLinks = 0;
    for (const Link& l : links)
      responses.push_back(l.response), starLinks += l.byStars ? 1 : 0;
    std::nth_element(responses.begin(), responses.begin() + responses.size() / 2, responses.end());
    out.ok = true;
    out.response = responses[responses.size() / 2];
    out.links = static_cast<int>(links.size());
    out.starLinks = starLinks;
    out.rate = next;
    out.blocks = std::move(blocks);
    const bool stable = sameShifts(layout, out.blocks, dt, rate, next);
    rate = next;
    if (stable) break;
  }
  out.parts.add(stackParts);
  out.parts.add(threadTime);
  if (!out.ok) return out;
  double ss = 0.0;
  for (const SkyRateBlock& b : out.blocks)
    ss += b.offsetPx.vx * b.offsetPx.vx + b.offsetPx.vy * b.offsetPx.vy;
  out.residualRmsPx = std::sqrt(ss / static_cast<double>(out.blocks.size()));
  return out;
}

}  // namespace st::detect::detail

namespace st::detect {

std::vector<double> doubleMeans(const ShiftedSums& sums) {
  std::vector<double> out(sums.sum.size());
  for (std::size_t i = 0; i < out.size(); ++i)
    out[i] = sums.count[i] > 0 ? sums.sum[i] / sums.count[i] : 0.0;
  return out;
}

std::vector<ShiftedSums> shiftedSums(const FrameCube& cube, const std::vector<ShiftedBlock>& blocks,
                                     double background) {
  std::vector<ShiftedSums> out(blocks.size());
  parallelFor(blocks.size(), 1, [&](std::size_t b0, std::size_t b1) {
    for (std::size_t b = b0; b < b1; ++b) {
      out[b].sum.assign(cube.framePixels(), 0.0);
      out[b].count.assign(cube.framePixels(), 0.0);
    }
  });
  // In tasks of one block's band of rows: one task per block left most threads idle for the last blocks
  // (20 blocks on 16 threads: two rounds, the second a quarter full; perf, H100, 2026-11-28).
  constexpr int kBandRows = 16;
  const int h = cube.height();
  const std::size_t bands = static_cast<std::size_t>((h + kBandRows - 1) / kBandRows);
  parallelFor(blocks.size() * bands, 1, [&](std::size_t t0, std::size_t t1) {
    for (std::size_t t = t0; t < t1; ++t) {
      const std::size_t b = t / bands;
      const int y0 = static_cast<int>(t % bands) * kBandRows;
      detail::addShifted(cube, blocks[b], background, out[b].sum.data(), out[b].count.data(), y0,
                         std::min(h, y0 + kBandRows));
    }
  });
  return out;
}

}  // namespace st::detect

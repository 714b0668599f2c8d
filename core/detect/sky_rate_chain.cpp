#include "sky_rate_chain.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <iterator>
#include <numeric>
#include <optional>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#endif

#include <Eigen/Dense>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "sky_rate_match.hpp"
#include "st/common/parallel.hpp"

namespace st::detect::detail {
namespace {

// A stack pixel is used when at least this fraction of its block's frames contributed to it (masked
// samples, a hot pixel or a cosmic ray, may be missing).
constexpr double kFullCoverage = 0.97;
// Sources paired between blocks peak at >= 2 times the detection threshold (log1p(1) compressed); the
// windowed centroids weigh them by their precision.
const double kPairPeak = std::log1p(1.0);
// The variance given to an offset from the phase correlation's peak alone (its sub-pixel interpolation is
// good to ~0.3 px, and a bright mover pulls it), px^2.
constexpr double kPhaseVarPx2 = 0.3 * 0.3;

// One block stacked at the current rate about its own mean time: a star at x_ref + u t in the frames sits
// in the stack at x_ref + u tS - meanShift (u the true rate), since frame n is shifted by the whole pixels
// round(v (t_n - tS)) of the current rate v. Single precision, 9 bytes a pixel: every block is held at once.
struct BlockStack {
  cv::Mat value;    // CV_32F, mean of F_n - background where covered, else 0
  cv::Mat noise;    // CV_32F, sigma / sqrt(frames contributing)
  cv::Mat covered;  // CV_8U, 255 where (nearly) every frame of the block contributed
  double tS = 0.0;  // mean t_n - t_ref over the block
  cv::Point2d meanShift;
};

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

// The blocks' stacks at `rate`: their sums from `provider` when it makes them, else on the CPU (in parallel
// over the blocks).
std::vector<BlockStack> stackBlocks(const FrameCube& cube, const Layout& layout, Velocity rate,
                                    double background, double sigma, const std::vector<double>& dt,
                                    const ShiftedSumsProvider* provider, CancelToken& cancel,
                                    TimedParts& parts) {
  PartTimer timer(parts);
  const std::size_t k = layout.count();
  const int w = cube.width(), h = cube.height();
  std::vector<BlockStack> stacks(k);
  std::vector<ShiftedBlock> blocks(k);
  for (std::size_t b = 0; b < k; ++b)
    blocks[b] = blockShifts(layout.first[b], layout.first[b + 1], rate, dt, stacks[b]);
  std::optional<std::vector<ShiftedSums>> made;
  if (provider && *provider) {
    made = (*provider)(cube, blocks, background, ShiftedSumsForm::SumsOrMeans);
    // Each block's sums and counts, or its means and counts, of the frame's size; else the CPU's.
    const std::size_t np = cube.framePixels();
    auto whole = [np](const ShiftedSums& b) {
      return (b.sum.size() == np && b.count.size() == np) || (b.mean.size() == np && b.frames.size() == np);
    };
    if (made && (made->size() != k || !std::all_of(made->begin(), made->end(), whole))) made.reset();
  }
  if (made) {
    timer.lap("stacks: sums made elsewhere");
    parallelFor(k, 1, [&](std::size_t b0, std::size_t b1) {
      for (std::size_t b = b0; b < b1; ++b)
        finishBlock(stacks[b], blocks[b], (*made)[b], w, h, sigma);
    });
    timer.lap("stacks: finished");
    return stacks;
  }
  // On the CPU, as many blocks at a time as there are threads (each block's sums are two frame-sized double
  // images), each group's sums made by bands of rows on every thread.
  const std::size_t group = std::max<unsigned>(1, workerCount());
  for (std::size_t g0 = 0; g0 < k; g0 += group) {
    cancel.throwIfCancelled();
    const std::size_t g1 = std::min(k, g0 + group);
    const std::vector<ShiftedBlock> some(blocks.begin() + static_cast<std::ptrdiff_t>(g0),
                                         blocks.begin() + static_cast<std::ptrdiff_t>(g1));
    const std::vector<ShiftedSums> sums = detect::shiftedSums(cube, some, background);
    parallelFor(g1 - g0, 1, [&](std::size_t b0, std::size_t b1) {
      for (std::size_t b = b0; b < b1; ++b)
        finishBlock(stacks[g0 + b], blocks[g0 + b], sums[b], w, h, sigma);
    });
  }
  return stacks;
}

// out(x, y) = in(x + gx, y + gy), zero where that falls outside `in`.
cv::Mat translated(const cv::Mat& in, int gx, int gy) {
  cv::Mat out = cv::Mat::zeros(in.size(), in.type());
  const int w = in.cols, h = in.rows;
  const int x0 = std::max(0, -gx), x1 = std::min(w, w - gx), y0 = std::max(0, -gy), y1 = std::min(h, h - gy);
  if (x1 <= x0 || y1 <= y0) return out;
  in(cv::Rect(x0 + gx, y0 + gy, x1 - x0, y1 - y0)).copyTo(out(cv::Rect(x0, y0, x1 - x0, y1 - y0)));
  return out;
}

struct Link {
  std::size_t i = 0, j = 0;
  cv::Point2d d;    // P_j - P_i, px: the star field's motion from block i to block j
  cv::Point2d var;  // its variance along x and y, px^2
  double response = 0.0;
  bool byStars = false;  // from the paired stars' windowed centroids (else the phase correlation's peak)
};

// A stack (or a translated one) as a linear image, valid where `valid`: its single-precision images as they
// are (the readers widen each value to double, as a CV_64F copy did: 0.27 CPU-s of conversions a
// pre-processing of the paper's cube, issue 16).
LinearImage linearImage(const cv::Mat& value, const cv::Mat& noise, const cv::Mat& valid) {
  return {value, noise, valid};
}

// The thresholded, compressed image that finds and pairs the sources: log1p(v / t) where v > t =
// detectSigma * noise, else 0 (and 0 where not valid).
cv::Mat compressed(const LinearImage& l, double detectSigma) {
  cv::Mat out(l.value.size(), CV_64F);  // every pixel written below
  for (int y = 0; y < out.rows; ++y) {
    const float* v = l.value.ptr<float>(y);
    const float* n = l.noise.ptr<float>(y);
    const unsigned char* ok = l.valid.ptr<unsigned char>(y);
    double* o = out.ptr<double>(y);
    for (int x = 0; x < out.cols; ++x) {
      const double t = detectSigma * n[x];
      o[x] = ok[x] && t > 0.0 && v[x] > t ? std::log1p(v[x] / t) : 0.0;
    }
  }
  return out;
}

// a & translated(b, gx, gy) for 0/255 masks, in one pass; `count` gets its non-zero pixels.
cv::Mat bothCovered(const cv::Mat& a, const cv::Mat& b, int gx, int gy, int* count) {
  cv::Mat out(a.size(), CV_8U);
  const int w = a.cols, h = a.rows;
  const int x0 = std::max(0, -gx), x1 = std::min(w, w - gx);
  int n = 0;
  for (int y = 0; y < h; ++y) {
    unsigned char* o = out.ptr<unsigned char>(y);
    const int by = y + gy;
    if (by < 0 || by >= h || x1 <= x0) {
      std::memset(o, 0, static_cast<std::size_t>(w));
      continue;
    }
    const unsigned char* pa = a.ptr<unsigned char>(y);
    const unsigned char* pb = b.ptr<unsigned char>(by);
    std::memset(o, 0, static_cast<std::size_t>(x0));
    for (int x = x0; x < x1; ++x) {
      o[x] = pa[x] & pb[x + gx];
      n += o[x] != 0;
    }
    std::memset(o + x1, 0, static_cast<std::size_t>(w - x1));
  }
  *count = n;
  return out;
}

// A link's images: block j's stack moved by the whole pixels (gx, gy) the current rate predicts, both cut to
// where both are fully covered; linear (for the windowed centroids) and compressed (for the phase
// correlation and the pairing, CV_64F).
struct LinkImages {
  int gx = 0, gy = 0;
  LinearImage la, lb;
  cv::Mat ia, ib;
};

// Block i's and block j's link images. False when the two share no covered pixel.
bool linkImages(const BlockStack& a, const BlockStack& b, Velocity rate, const SkyRateParams& params,
                LinkImages* im) {
  const double ex = rate.vx * (b.tS - a.tS) - b.meanShift.x + a.meanShift.x;
  const double ey = rate.vy * (b.tS - a.tS) - b.meanShift.y + a.meanShift.y;
  im->gx = static_cast<int>(std::lround(ex));
  im->gy = static_cast<int>(std::lround(ey));
  int covered = 0;
  const cv::Mat both = bothCovered(a.covered, b.covered, im->gx, im->gy, &covered);
  if (covered == 0) return false;
  im->la = linearImage(a.value, a.noise, both);
  im->lb = linearImage(translated(b.value, im->gx, im->gy), translated(b.noise, im->gx, im->gy), both);
  im->ia = compressed(im->la, params.detectSigma);
  im->ib = compressed(im->lb, params.detectSigma);
  return true;
}

// The rest of a link from its phase correlation (the offset d of the compressed images, the response r):
// the windowed centroids of the stars paired at that offset on the linear images replace d when there are
// enough of them. False when the response is too weak.
bool finishLink(const BlockStack& a, const BlockStack& b, const LinkImages& im, cv::Point2d d, double r,
                const SkyRateParams& params, Link* link) {
  if (!(r >= params.minResponse)) return false;
  cv::Point2d c;
  link->byStars = windowedOffset(im.la, im.lb, pairSources(im.ia, im.ib, d, kPairPeak), &c, &link->var);
  if (link->byStars) {
    d = c;
  } else {
    link->var = {kPhaseVarPx2, kPhaseVarPx2};
  }
  link->response = r;
  link->d = {im.gx + d.x + b.meanShift.x - a.meanShift.x, im.gy + d.y + b.meanShift.y - a.meanShift.y};
  return true;
}

// Compares blocks i and j on this thread: their link images, the residual offset coarsely by phase
// correlation, then by the windowed centroids of the paired stars on the linear stacks (one validity mask
// for both, so that a window cut by it is cut alike in both). False when they share no reliable star
// pattern.
bool measureLink(const BlockStack& a, const BlockStack& b, Velocity rate, const cv::Mat& window,
                 const SkyRateParams& params, Link* link, TimedParts* parts) {
  PartTimer timer(*parts);  // its seconds are this thread's; its CPU time is not used
  LinkImages im;
  if (!linkImages(a, b, rate, params, &im)) return false;
  timer.lap("links' images (thread time)");
  double r = 0.0;
  const cv::Point2d d = phaseShift(im.ia, im.ib, window, &r);
  timer.lap("phase correlations (thread time)");
  const bool ok = finishLink(a, b, im, d, r, params, link);
  timer.lap("paired stars (thread time)");
  return ok;
}

// True when the links connect every block to block 0.
bool connected(std::size_t blocks, const std::vector<Link>& links) {
  std::vector<std::size_t> parent(blocks);
  std::iota(parent.begin(), parent.end(), 0);
  auto root = [&](std::size_t k) {
    while (parent[k] != k)
      k = parent[k] = parent[parent[k]];
    return k;
  };
  for (const Link& l : links)
    parent[root(l.i)] = root(l.j);
  for (std::size_t k = 1; k < blocks; ++k)
    if (root(k) != root(0)) return false;
  return true;
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

// measureLinks' comparisons with the phase correlations made elsewhere (a device, issue 16), in groups of
// one link per worker thread (a group's images, ~8.5 MB a link of 512^2, are freed before the next group's
// are made: all 54 links' at once were ~460 MB of fresh pages, which doubled the images' thread time on an
// H200 host). Per group, the provider asks for each link's images as it fills its staging (on every core;
// where a staging buffer holds fewer pairs than a group, beside its transfers and transforms of the
// previous ones), then each link's paired stars are measured in parallel. A link the provider did not make
// (a pair it gave back not ok, a group it failed part way) is correlated here. A provider that declines a
// group without asking for any image (a benchmark knob, a device that failed before, images it does not
// take) leaves that group and the rest to `cpu` (the CPU's own path, all of them in one parallel loop). The
// wall time of the provider's calls, the images included, is one part of `threadTime` (no thread's).
void measureLinksCorrelatedElsewhere(const std::vector<BlockStack>& stacks, Velocity rate, const cv::Mat& window,
                                     const SkyRateParams& params, const PhaseCorrelationProvider& correlate,
                                     CancelToken& cancel, std::vector<Link>& tried, std::vector<char>& ok,
                                     std::vector<TimedParts>& parts, TimedParts* threadTime,
                                     const std::function<void(std::size_t first)>& cpu) {
  const std::size_t group = std::max<std::size_t>(4, workerCount());
  std::vector<LinkImages> images(std::min(group, tried.size()));
  std::vector<char> made(images.size());
  for (std::size_t g0 = 0; g0 < tried.size(); g0 += group) {
    const std::size_t n = std::min(group, tried.size() - g0);
    std::fill(made.begin(), made.end(), 0);
    // Link g0 + q's images into images[q] (made[q]; ok says whether the blocks overlap).
    auto makeImages = [&](std::size_t q) {
      const std::size_t l = g0 + q;
      PartTimer timer(parts[l]);
      ok[l] = linkImages(stacks[tried[l].i], stacks[tried[l].j], rate, params, &images[q]);
      made[q] = 1;
      timer.lap("links' images (thread time)");
    };
    PhaseCorrelationBatch batch;
    batch.width = stacks.front().value.cols;
    batch.height = stacks.front().value.rows;
    batch.nx = cv::getOptimalDFTSize(batch.width);
    batch.ny = cv::getOptimalDFTSize(batch.height);
    batch.pairs = n;
    batch.fill = [&](std::size_t q, float* a, float* b) {
      makeImages(q);
      if (ok[g0 + q]) {
        windowedFloats(images[q].ia, window, a, static_cast<std::size_t>(batch.width));
        windowedFloats(images[q].ib, window, b, static_cast<std::size_t>(batch.width));
      } else {  // blocks that share no pixel: correlated as zeros, the result not used
        std::fill(a, a + static_cast<std::size_t>(batch.width) * batch.height, 0.0f);
        std::fill(b, b + static_cast<std::size_t>(batch.width) * batch.height, 0.0f);
      }
    };
    std::optional<std::vector<PhasePeak>> peaks;
    {
      PartTimer timer(*threadTime);
      peaks = correlate(batch);
      if (peaks && peaks->size() != n) peaks.reset();
      timer.lap("links' images and phase correlations elsewhere (wall)");
    }
    if (!peaks && std::none_of(made.begin(), made.begin() + static_cast<std::ptrdiff_t>(n),
                               [](char m) { return m != 0; })) {
      cpu(g0);
      return;
    }
    cancel.throwIfCancelled();
    parallelFor(n, 1, [&](std::size_t q0, std::size_t q1) {
      for (std::size_t q = q0; q < q1; ++q) {
        cancel.throwIfCancelled();
        const std::size_t l = g0 + q;
        if (!made[q]) makeImages(q);
        if (!ok[l]) continue;
        PartTimer timer(parts[l]);
        double r = 0.0;
        cv::Point2d d;
        if (peaks && (*peaks)[q].ok) {
          d = {(*peaks)[q].dx, (*peaks)[q].dy};
          r = (*peaks)[q].response;
        } else {
          d = phaseShift(images[q].ia, images[q].ib, window, &r);
          timer.lap("phase correlations (thread time)");
        }
        ok[l] = finishLink(stacks[tried[l].i], stacks[tried[l].j], images[q], d, r, params, &tried[l]);
        images[q] = LinkImages();  // freed on the thread that used it last
        timer.lap("paired stars (thread time)");
      }
    });
  }
}

// The links of one iteration: every pair of blocks whose stars have moved at most linkFraction of the frame
// between them (neighbours always), measured in parallel; failed comparisons are left out.
std::vector<Link> measureLinks(const std::vector<BlockStack>& stacks, Velocity rate, const cv::Mat& window,
                               const SkyRateParams& params, int width, int height, CancelToken& cancel,
                               const PhaseCorrelationProvider* correlate, TimedParts* threadTime) {
  const std::size_t k = stacks.size();
  std::vector<Link> tried;
  for (std::size_t i = 0; i < k; ++i)
    for (std::size_t j = i + 1; j < k; ++j) {
      const double t = stacks[j].tS - stacks[i].tS;
      if (j > i + 1 && (std::fabs(rate.vx * t) > params.chainLinkFraction * width ||
                        std::fabs(rate.vy * t) > params.chainLinkFraction * height))
        continue;
      tried.push_back({i, j, {}, {}, 0.0, false});
    }
  std::vector<char> ok(tried.size(), 0);
  std::vector<TimedParts> parts(tried.size());
  // Links [first, end) on the CPU, each on a thread of its own.
  const auto onCpu = [&](std::size_t first) {
    parallelFor(tried.size() - first, 1, [&](std::size_t l0, std::size_t l1) {
      for (std::size_t l = first + l0; l < first + l1; ++l) {
        cancel.throwIfCancelled();
        ok[l] =
            measureLink(stacks[tried[l].i], stacks[tried[l].j], rate, window, params, &tried[l], &parts[l]);
      }
    });
  };
  if (correlate && *correlate && !tried.empty()) {
    measureLinksCorrelatedElsewhere(stacks, rate, window, params, *correlate, cancel, tried, ok, parts,
                                    threadTime, onCpu);
  } else {
    onCpu(0);
  }
  for (const TimedParts& p : parts)
    for (const TimedPart& q : p.parts)
      threadTime->add(q.name, q.seconds);  // summed over the threads: no wall or CPU meaning of its own
  std::vector<Link> links;
  for (std::size_t l = 0; l < tried.size(); ++l)
    if (ok[l]) links.push_back(tried[l]);
  // The paired stars' links alone when they connect every block: the phase correlation's peak is coarse.
  std::vector<Link> byStars;
  std::copy_if(links.begin(), links.end(), std::back_inserter(byStars),
               [](const Link& l) { return l.byStars; });
  if (connected(k, byStars)) return byStars;
  return links;
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
  for (int it = 0; it < 4; ++it) {
    const std::vector<BlockStack> stacks =
        stackBlocks(cube, layout, rate, background, sigma, dt, sums, cancel, stackParts);
    timer.lap("stacks");
    const std::vector<Link> links =
        measureLinks(stacks, rate, window, params, cube.width(), cube.height(), cancel, correlate, &threadTime);
    timer.lap("links");
    out.iterations = it + 1;
    if (!connected(k, links)) {
      // A later iteration that loses the chain keeps the earlier one's result.
      if (!out.ok)
        out.why = "the " + std::to_string(k) + " blocks could not all be linked by shared stars (" +
                  std::to_string(links.size()) + " links)";
      break;
    }
    std::vector<double> responses;
    int starLinks = 0;
    for (const Link& l : links)
      responses.push_back(l.response), starLinks += l.byStars ? 1 : 0;
    std::vector<SkyRateBlock> blocks(k);
    for (std::size_t b = 0; b < k; ++b)
      blocks[b] = {layout.first[b], layout.first[b + 1], stacks[b].tS, {}};
    Velocity next;
    solve(links, blocks, &next);
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

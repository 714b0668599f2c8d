#include "sky_rate_links.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <iterator>
#include <numeric>
#include <optional>

#include <opencv2/imgproc.hpp>

#include "sky_rate_match.hpp"
#include "st/common/parallel.hpp"

namespace st::detect::detail {
namespace {

// Sources paired between blocks peak at >= 2 times the detection threshold (log1p(1) compressed); the
// windowed centroids weigh them by their precision.
const double kPairPeak = std::log1p(1.0);
// The variance given to an offset from the phase correlation's peak alone (its sub-pixel interpolation is
// good to ~0.3 px, and a bright mover pulls it), px^2.
constexpr double kPhaseVarPx2 = 0.3 * 0.3;

// out(x, y) = in(x + gx, y + gy), zero where that falls outside `in`.
cv::Mat translated(const cv::Mat& in, int gx, int gy) {
  cv::Mat out = cv::Mat::zeros(in.size(), in.type());
  const int w = in.cols, h = in.rows;
  const int x0 = std::max(0, -gx), x1 = std::min(w, w - gx), y0 = std::max(0, -gy), y1 = std::min(h, h - gy);
  if (x1 <= x0 || y1 <= y0) return out;
  in(cv::Rect(x0 + gx, y0 + gy, x1 - x0, y1 - y0)).copyTo(out(cv::Rect(x0, y0, x1 - x0, y1 - y0)));
  return out;
}

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

// The whole pixels (gx, gy) the rate predicts the star field moves from block a's stack to block b's.
void wholeShift(const BlockStack& a, const BlockStack& b, Velocity rate, int* gx, int* gy) {
  const double ex = rate.vx * (b.tS - a.tS) - b.meanShift.x + a.meanShift.x;
  const double ey = rate.vy * (b.tS - a.tS) - b.meanShift.y + a.meanShift.y;
  *gx = static_cast<int>(std::lround(ex));
  *gy = static_cast<int>(std::lround(ey));
}

// A link's images: block j's stack moved by the whole pixels (gx, gy) the current rate predicts, both cut to
// where both are fully covered; linear (for the windowed centroids) and compressed (for the phase
// correlation and the pairing, CV_64F).
struct LinkImages {
  int gx = 0, gy = 0;
  LinearImage la, lb;
  cv::Mat ia, ib;
};

// Each block's compressed image over its own covered pixels (compressed() of {value, noise, covered}), made
// once for all the links it takes part in (issue 16: ~5 links a block on the paper's cube). A link's
// compressed image is its block's where both blocks are covered, else 0: compressed() of the link's linear
// image, value for value (a pixel both cover is one its own block covers, and moved by whole pixels).
std::vector<cv::Mat> compressedBlocks(const std::vector<BlockStack>& stacks, const std::vector<Link>& links,
                                      double detectSigma) {
  std::vector<cv::Mat> out(stacks.size());
  std::vector<char> used(stacks.size(), 0);
  for (const Link& l : links)
    used[l.i] = used[l.j] = 1;
  parallelFor(stacks.size(), 1, [&](std::size_t k0, std::size_t k1) {
    for (std::size_t k = k0; k < k1; ++k)
      if (used[k])
        out[k] = compressed(linearImage(stacks[k].value, stacks[k].noise, stacks[k].covered), detectSigma);
  });
  return out;
}

// `full` (CV_64F) moved by (gx, gy) as translated() does, where `both` is set; 0 elsewhere.
cv::Mat maskedCompressed(const cv::Mat& full, const cv::Mat& both, int gx, int gy) {
  cv::Mat out(full.size(), CV_64F);
  const int w = full.cols, h = full.rows;
  for (int y = 0; y < h; ++y) {
    const unsigned char* ok = both.ptr<unsigned char>(y);
    double* o = out.ptr<double>(y);
    const int by = y + gy;
    const double* in = by >= 0 && by < h ? full.ptr<double>(by) : nullptr;
    for (int x = 0; x < w; ++x) {
      const int bx = x + gx;
      // A pixel both cover lies inside the moved block (bothCovered).
      o[x] = ok[x] && in && bx >= 0 && bx < w ? in[bx] : 0.0;
    }
  }
  return out;
}

// Block i's and block j's link images (their compressed images from `fullA` and `fullB`, compressedBlocks'
// when given, else made here). False when the two share no covered pixel.
bool linkImages(const BlockStack& a, const BlockStack& b, Velocity rate, const SkyRateParams& params,
                LinkImages* im, const cv::Mat* fullA = nullptr, const cv::Mat* fullB = nullptr) {
  wholeShift(a, b, rate, &im->gx, &im->gy);
  int covered = 0;
  const cv::Mat both = bothCovered(a.covered, b.covered, im->gx, im->gy, &covered);
  if (covered == 0) return false;
  im->la = linearImage(a.value, a.noise, both);
  im->lb = linearImage(translated(b.value, im->gx, im->gy), translated(b.noise, im->gx, im->gy), both);
  im->ia = fullA && !fullA->empty() ? maskedCompressed(*fullA, both, 0, 0)
                                    : compressed(im->la, params.detectSigma);
  im->ib = fullB && !fullB->empty() ? maskedCompressed(*fullB, both, im->gx, im->gy)
                                    : compressed(im->lb, params.detectSigma);
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
                 const SkyRateParams& params, Link* link, TimedParts* parts, const cv::Mat* fullA,
                 const cv::Mat* fullB) {
  PartTimer timer(*parts);  // its seconds are this thread's; its CPU time is not used
  LinkImages im;
  if (!linkImages(a, b, rate, params, &im, fullA, fullB)) return false;
  timer.lap("links' images (thread time)");
  double r = 0.0;
  const cv::Point2d d = phaseShift(im.ia, im.ib, window, &r);
  timer.lap("phase correlations (thread time)");
  const bool ok = finishLink(a, b, im, d, r, params, link);
  timer.lap("paired stars (thread time)");
  return ok;
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
void measureLinksCorrelatedElsewhere(const std::vector<BlockStack>& stacks, Velocity rate,
                                     const cv::Mat& window, const SkyRateParams& params,
                                     const PhaseCorrelationProvider& correlate, CancelToken& cancel,
                                     std::vector<Link>& tried, std::vector<char>& ok,
                                     std::vector<TimedParts>& parts, TimedParts* threadTime,
                                     const std::vector<cv::Mat>& full,
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
      ok[l] = linkImages(stacks[tried[l].i], stacks[tried[l].j], rate, params, &images[q], &full[tried[l].i],
                         &full[tried[l].j]);
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

}  // namespace

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

// The links of one iteration: every pair of blocks whose stars have moved at most linkFraction of the frame
// between them (neighbours always), measured in parallel; failed comparisons are left out.
std::vector<Link> measureLinks(const std::vector<BlockStack>& stacks, Velocity rate, const cv::Mat& window,
                               const SkyRateParams& params, int width, int height, CancelToken& cancel,
                               const PhaseCorrelationProvider* correlate, TimedParts* threadTime,
                               const std::vector<char>& sameStacks, TriedLinks& before, int* kept,
                               bool neighboursOnly) {
  const std::size_t k = stacks.size();
  std::vector<Link> tried;
  for (std::size_t i = 0; i < k; ++i)
    for (std::size_t j = i + 1; j < k; ++j) {
      const double t = stacks[j].tS - stacks[i].tS;
      if (j > i + 1 && (neighboursOnly || std::fabs(rate.vx * t) > params.chainLinkFraction * width ||
                        std::fabs(rate.vy * t) > params.chainLinkFraction * height))
        continue;
      Link l{i, j, {}, {}, 0.0, false};
      wholeShift(stacks[i], stacks[j], rate, &l.gx, &l.gy);
      tried.push_back(l);
    }
  std::vector<char> ok(tried.size(), 0);
  // The links the previous iteration measured on the same images are taken as they were; the rest, `todo`,
  // are measured below as `measured`.
  std::vector<std::size_t> todo;
  for (std::size_t l = 0; l < tried.size(); ++l) {
    const Link& t = tried[l];
    const bool same =
        t.i < sameStacks.size() && t.j < sameStacks.size() && sameStacks[t.i] && sameStacks[t.j];
    const auto was = std::find_if(before.links.begin(), before.links.end(), [&](const Link& b) {
      return b.i == t.i && b.j == t.j && b.gx == t.gx && b.gy == t.gy;
    });
    if (same && was != before.links.end()) {
      const auto at = static_cast<std::size_t>(was - before.links.begin());
      tried[l] = *was;
      ok[l] = before.ok[at];
      ++*kept;
    } else {
      todo.push_back(l);
    }
  }
  std::vector<Link> measured;
  for (std::size_t l : todo)
    measured.push_back(tried[l]);
  std::vector<char> measuredOk(measured.size(), 0);
  std::vector<TimedParts> parts(measured.size());
  const std::vector<cv::Mat> full = compressedBlocks(stacks, measured, params.detectSigma);
  // Links [first, end) of `measured` on the CPU, each on a thread of its own.
  const auto onCpu = [&](std::size_t first) {
    parallelFor(measured.size() - first, 1, [&](std::size_t l0, std::size_t l1) {
      for (std::size_t l = first + l0; l < first + l1; ++l) {
        cancel.throwIfCancelled();
        measuredOk[l] = measureLink(stacks[measured[l].i], stacks[measured[l].j], rate, window, params,
                                    &measured[l], &parts[l], &full[measured[l].i], &full[measured[l].j]);
      }
    });
  };
  if (correlate && *correlate && !measured.empty()) {
    measureLinksCorrelatedElsewhere(stacks, rate, window, params, *correlate, cancel, measured, measuredOk,
                                    parts, threadTime, full, onCpu);
  } else {
    onCpu(0);
  }
  for (std::size_t q = 0; q < todo.size(); ++q) {
    tried[todo[q]] = measured[q];
    ok[todo[q]] = measuredOk[q];
  }
  before = {tried, ok};
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

}  // namespace st::detect::detail

#include "st/detect/sky_rate.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "sky_rate_chain.hpp"
#include "sky_rate_match.hpp"
#include "st/common/parallel.hpp"

namespace st::detect {
namespace {

using detail::consensusOffset;
using detail::phaseShift;

struct Block {
  cv::Mat image;  // CV_64F
  double tS = 0.0;
};

// The mean of a block with no shifts minus the background; unmasked samples only (0 where none): the chain's
// block sums (each pixel's frames in order, AVX2 where the CPU has it), divided as doubleMeans does.
std::vector<double> meanOf(const FrameCube& cube, const ShiftedBlock& still, double background) {
  ShiftedSums s;
  s.sum.assign(cube.framePixels(), 0.0);
  s.count.assign(cube.framePixels(), 0.0);
  detail::addShifted(cube, still, background, s.sum.data(), s.count.data(), 0, cube.height());
  return doubleMeans(s);
}

// The halves of a block of frames [first, last) (the first alone when it has one frame): a block's image is
// the smaller of their means, so that a cosmic ray (in one frame, one half) does not survive while a star
// (in both) does.
std::vector<ShiftedBlock> halvesOf(std::size_t first, std::size_t last) {
  const std::size_t mid = first + std::max<std::size_t>(1, (last - first) / 2);
  auto still = [](std::size_t a, std::size_t b) {
    return ShiftedBlock{a, b, std::vector<int>(b - a, 0), std::vector<int>(b - a, 0)};
  };
  if (mid >= last) return {still(first, last)};
  return {still(first, mid), still(mid, last)};
}

// A block's image from the means of its halves: the smaller of them, then faint pixels zeroed and the rest
// compressed.
Block blockImage(const std::vector<cv::Mat>& halfMeans, std::size_t first, std::size_t last, double sigma,
                 double detectSigma, const std::vector<double>& dt) {
  Block b;
  // (A copy of a single half: the means may be the caller's buffers.)
  b.image = halfMeans.size() == 2 ? cv::Mat(cv::min(halfMeans[0], halfMeans[1])) : halfMeans[0].clone();
  for (std::size_t n = first; n < last; ++n)
    b.tS += dt[n];
  b.tS /= static_cast<double>(last - first);
  const double thr =
      detectSigma * sigma / std::sqrt(std::max<double>(1.0, static_cast<double>(last - first) / 2));
  for (int y = 0; y < b.image.rows; ++y) {
    double* row = b.image.ptr<double>(y);
    for (int x = 0; x < b.image.cols; ++x) {
      const double v = row[x];
      // Bright sources only, compressed so that one saturated star does not decide alone.
      row[x] = v > thr ? std::log1p(v / thr) : 0.0;
    }
  }
  return b;
}

// The halves' means made by `sums` (DoubleMeans: the same sums and division as meanOf's); none when it
// makes none or not one of the frame's size for every half.
std::optional<std::vector<ShiftedSums>> halfMeansElsewhere(const FrameCube& cube,
                                                           const std::vector<ShiftedBlock>& halves,
                                                           double background,
                                                           const ShiftedSumsProvider* sums) {
  if (!sums || !*sums) return std::nullopt;
  std::optional<std::vector<ShiftedSums>> made =
      (*sums)(cube, halves, background, ShiftedSumsForm::DoubleMeans);
  const std::size_t np = cube.framePixels();
  if (made && (made->size() != halves.size() || !std::all_of(made->begin(), made->end(), [np](const auto& m) {
                 return m.doubleMean.size() == np;
               })))
    made.reset();
  return made;
}

std::string fixed(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.4f", v);
  return buf;
}

double median(std::vector<double> v) {
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

// The rates of pairs of short adjacent blocks spread over the cube (short so that drifting stars do not
// streak much), with each pair's phase-correlation peak and time span.
struct PairRates {
  std::vector<double> vx, vy, responses, spans;
};

PairRates blockPairRates(const FrameCube& cube, std::size_t len, double background, double sigma,
                         const SkyRateParams& params, CancelToken& cancel, const ShiftedSumsProvider* sums,
                         TimedParts& parts) {
  PartTimer timer(parts);
  const std::size_t nf = cube.frameCount();
  const int pairs = std::max(1, params.blocks);
  const auto dt = cube.timeOffsetsS();
  cv::Mat window;
  cv::createHanningWindow(window, cv::Size(cube.width(), cube.height()), CV_64F);
  // The pairs are independent: their 2 x `pairs` block means made in parallel (or by `sums`: a device's,
  // issue 16), then the pairs' phase correlations (serial before issue 16; one task per block, not per pair,
  // since 2026-11-28: the 8 pairs took 0.05-0.06 s on 16 threads), gathered in order as before.
  struct One {
    bool ok = false;
    double vx = 0.0, vy = 0.0, response = 0.0, span = 0.0;
  };
  std::vector<One> each(static_cast<std::size_t>(pairs));
  std::vector<std::size_t> firsts(2 * each.size());
  std::vector<ShiftedBlock> halves;
  std::vector<std::size_t> halfStart(firsts.size() + 1, 0);
  for (std::size_t j = 0; j < firsts.size(); ++j) {
    const std::size_t k = j / 2;
    const std::size_t start = pairs > 1 ? (nf - 2 * len) * k / static_cast<std::size_t>(pairs - 1) : 0;
    firsts[j] = start + (j % 2) * len;
    for (ShiftedBlock& h : halvesOf(firsts[j], firsts[j] + len))
      halves.push_back(std::move(h));
    halfStart[j + 1] = halves.size();
  }
  std::optional<std::vector<ShiftedSums>> elsewhere = halfMeansElsewhere(cube, halves, background, sums);
  std::vector<Block> blocks(firsts.size());
  parallelFor(blocks.size(), 1, [&](std::size_t j0, std::size_t j1) {
    for (std::size_t j = j0; j < j1; ++j) {
      cancel.throwIfCancelled();
      // The means wrapped, not copied (blockImage makes the block's own image from them).
      std::vector<std::vector<double>> own(halfStart[j + 1] - halfStart[j]);
      std::vector<cv::Mat> means;
      for (std::size_t h = halfStart[j]; h < halfStart[j + 1]; ++h) {
        std::vector<double>& m = elsewhere ? (*elsewhere)[h].doubleMean
                                           : (own[h - halfStart[j]] = meanOf(cube, halves[h], background));
        means.emplace_back(cube.height(), cube.width(), CV_64F, m.data());
      }
      blocks[j] = blockImage(means, firsts[j], firsts[j] + len, sigma, params.detectSigma, dt);
    }
  });
  timer.lap("block pairs: means");
  parallelFor(each.size(), 1, [&](std::size_t k0, std::size_t k1) {
    for (std::size_t k = k0; k < k1; ++k) {
      cancel.throwIfCancelled();
      const Block& a = blocks[2 * k];
      const Block& b = blocks[2 * k + 1];
      double response = 0.0;
      cv::Point2d d = phaseShift(a.image, b.image, window, &response);
      cv::Point2d c;
      if (consensusOffset(a.image, b.image, d, detail::minPeakCompressed(), &c)) d = c;
      const double span = b.tS - a.tS;
      if (span <= 0) continue;
      each[k] = {true, d.x / span, d.y / span, response, span};
    }
  });
  timer.lap("block pairs: correlations");
  PairRates out;
  for (const One& e : each) {
    if (!e.ok) continue;
    out.vx.push_back(e.vx);
    out.vy.push_back(e.vy);
    out.responses.push_back(e.response);
    out.spans.push_back(e.span);
  }
  return out;
}

// The chain must agree with the block pairs within 3 times their robust scatter, and within 1 px over a
// pair's span: a wrong chain (stars mismatched all along) is far off, a right one within a fraction of that.
// `tol` gets the tolerance, px/s.
bool agrees(const PairRates& p, Velocity pairRate, Velocity chainRate, Velocity* tol) {
  auto scatter = [](const std::vector<double>& v, double m) {
    std::vector<double> dev;
    for (double x : v)
      dev.push_back(std::fabs(x - m));
    return 1.4826 * median(dev);
  };
  const double base = 1.0 / median(p.spans);
  *tol = {std::max(base, 3.0 * scatter(p.vx, pairRate.vx)), std::max(base, 3.0 * scatter(p.vy, pairRate.vy))};
  return std::fabs(chainRate.vx - pairRate.vx) <= tol->vx && std::fabs(chainRate.vy - pairRate.vy) <= tol->vy;
}

}  // namespace

SkyRate measureSkyRate(const FrameCube& cube, double background, double sigma, const SkyRateParams& params,
                       CancelToken& cancel, const ShiftedSumsProvider* sums,
                       const PhaseCorrelationProvider* correlate) {
  SkyRate out;
  const std::size_t nf = cube.frameCount();
  const std::size_t len =
      std::clamp<std::size_t>(nf / 8, 1, static_cast<std::size_t>(std::max(1, params.blockFrames)));
  if (nf < 2 * len || nf < 2 || cube.timeSpanS() <= 0.0) {
    out.note = "sky rate: fewer than two frames or no time span, assumed 0";
    return out;
  }
  PartTimer timer(out.parts);
  TimedParts pairParts;
  const PairRates pairs = blockPairRates(cube, len, background, sigma, params, cancel, sums, pairParts);
  timer.lap("block pairs");
  out.parts.add(pairParts);
  out.response = pairs.responses.empty() ? 0.0 : median(pairs.responses);
  if (pairs.vx.empty() || out.response < params.minResponse) {
    out.note = "sky rate: no reliable star pattern (phase-correlation peak " + std::to_string(out.response) +
               "), assumed 0";
    return out;
  }
  out.rate = {median(pairs.vx), median(pairs.vy)};
  out.blockPairRate = out.rate;
  out.reliable = true;
  const std::string pairText =
      "pairs of short blocks gave (" + fixed(out.rate.vx) + ", " + fixed(out.rate.vy) + ") px/s";
  const detail::ChainResult chain =
      detail::chainSkyRate(cube, out.rate, background, sigma, params, cancel, sums, correlate);
  timer.lap("chain");
  out.parts.add(chain.parts, "chain: ");
  if (!chain.ok) {
    out.note = "sky rate: " + pairText + "; not refined: " + chain.why;
    return out;
  }
  const std::string chainText =
      "chained over " + std::to_string(chain.blocks.size()) + " blocks (" + std::to_string(chain.links) +
      " links, " + std::to_string(chain.starLinks) + " by paired stars, " + std::to_string(chain.iterations) +
      (chain.iterations == 1 ? " iteration" : " iterations") +
      (chain.coarseFirst ? ", the first by neighbouring blocks only" : "") +
      (chain.iterations > 1 ? "; " + std::to_string(chain.stacksKept) + " stacks and " +
                                  std::to_string(chain.linksKept) + " links kept from the iteration before"
                            : std::string()) +
      ") gave (" + fixed(chain.rate.vx) + ", " + fixed(chain.rate.vy) + ") px/s";
  Velocity tol;
  if (!agrees(pairs, out.rate, chain.rate, &tol)) {
    out.note = "sky rate: " + pairText + ", kept; " + chainText + ", which disagrees (tolerance " +
               fixed(tol.vx) + ", " + fixed(tol.vy) + " px/s)";
    return out;
  }
  out.rate = chain.rate;
  out.response = chain.response;
  out.chained = true;
  out.blocks = chain.blocks;
  out.residualRmsPx = chain.residualRmsPx;
  out.note =
      "sky rate: " + pairText + "; " + chainText + ", residual rms " + fixed(chain.residualRmsPx) + " px";
  return out;
}

}  // namespace st::detect

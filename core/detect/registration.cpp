#include "st/detect/registration.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <numeric>
#include <optional>
#include <sstream>
#include <utility>

#include "registration_links.hpp"
#include "st/common/error.hpp"
#include "st/common/parallel.hpp"

namespace st::detect {
namespace {

using detail::Link;
using detail::linkSigmaPx;
using detail::measureLink;
using detail::StarImages;

constexpr int kQuickFrames = 64;        ///< links sampled on long sequences before measuring every frame
constexpr int kMaxBack = 3;             ///< a failed link is retried against up to this many earlier frames
constexpr double kBridgeSigmaPx = 5.0;  ///< error of a frame placed by the median rate (no significant link)

/// A frame's departure from the model is used only beyond this many sigmas of its measurement.
constexpr double kSignificance = 5.0;

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

/// Theil-Sen slope of p over t (time order), pairs at most `maxGap` apart (subsampled to ~20000 pairs).
double theilSen(const std::vector<double>& t, const std::vector<double>& p, std::size_t maxGap) {
  const std::size_t n = t.size();
  std::vector<double> slopes;
  const std::size_t pairs = n * std::min(maxGap, n);
  const std::size_t stride = std::max<std::size_t>(1, pairs / 20000);
  std::size_t k = 0;
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = i + 1; j < n && j <= i + maxGap; ++j) {
      if (k++ % stride != 0 || !(t[j] > t[i])) continue;
      slopes.push_back((p[j] - p[i]) / (t[j] - t[i]));
    }
  }
  return median(std::move(slopes));
}

/// Prefix sums of one axis for the segmented fit: the common rate of p over t with one free level per
/// segment, its residual sum of squares in O(segments).
class SegmentFit {
 public:
  SegmentFit(const std::vector<double>& t, const std::vector<double>& p) : m_n(t.size()) {
    m_s.assign(5 * (m_n + 1), 0.0);
    for (std::size_t k = 0; k < m_n; ++k) {
      const double v[5] = {t[k], p[k], t[k] * t[k], t[k] * p[k], p[k] * p[k]};
      for (int j = 0; j < 5; ++j)
        m_s[5 * (k + 1) + j] = m_s[5 * k + j] + v[j];
    }
  }
  /// Rate and residual sum of squares for segments [cuts_i, cuts_i+1); sxx: the within-segment sum of
  /// (t - mean)^2 (the rate's variance is sigma^2 / sxx).
  [[nodiscard]] double fit(const std::vector<std::size_t>& cuts, double& rss, double& sxx) const {
    double sxy = 0.0, syy = 0.0;
    sxx = 0.0;
    for (std::size_t i = 0; i + 1 < cuts.size(); ++i) {
      const std::size_t a = cuts[i], b = cuts[i + 1];
      const double n = static_cast<double>(b - a);
      const auto sum = [&](int j) { return m_s[5 * b + j] - m_s[5 * a + j]; };
      sxx += sum(2) - sum(0) * sum(0) / n;
      sxy += sum(3) - sum(0) * sum(1) / n;
      syy += sum(4) - sum(1) * sum(1) / n;
    }
    const double rate = sxx > 0.0 ? sxy / sxx : 0.0;
    rss = std::max(0.0, syy - rate * sxy);
    return rate;
  }

 private:
  std::size_t m_n;
  std::vector<double> m_s;
};

/// The linear rate of the chained positions (time order) for the per-frame model: a common rate with a
/// level per pointing, the pointings found by binary segmentation (at most 4 re-pointings, at least 3
/// frames each; a cut is kept when it removes more than max(12, 4 ln N) sigma^2 of squared residual, sigma
/// the frame-to-frame scatter from the median of successive differences).
/// An axis whose rate is not significant (below 3 sigma) is 0: dithers and re-pointings of a tracked
/// telescope do not make the stars drift. `note` says what was found.
Velocity robustRate(const std::vector<double>& t, const std::vector<double>& px,
                    const std::vector<double>& py, std::string& note) {
  const std::size_t n = t.size();
  std::vector<double> d;
  for (std::size_t k = 1; k < n; ++k)
    d.push_back(std::hypot(px[k] - px[k - 1], py[k] - py[k - 1]));
  // The 2-D distance of two independent Gaussian scatters of sigma per axis has median 1.1774 sqrt(2) sigma.
  const double sigma = std::max(1e-3, median(d) / (1.1774 * std::sqrt(2.0)));
  const SegmentFit fx(t, px), fy(t, py);
  std::vector<std::size_t> cuts{0, n};
  // A cut adds a level per axis and a position: kept above max(12, 4 ln N) sigma^2 (random dithers alone
  // reach ~2 ln N + 2).
  const double cutGain = std::max(12.0, 4.0 * std::log(static_cast<double>(n)));
  const auto total = [&](const std::vector<std::size_t>& c) {
    double rx = 0.0, ry = 0.0, sxx = 0.0;
    (void)fx.fit(c, rx, sxx);
    (void)fy.fit(c, ry, sxx);
    return rx + ry;
  };
  double rss = total(cuts);
  for (int jumps = 0; jumps < 4; ++jumps) {
    double best = rss;
    std::vector<std::size_t> bestCuts;
    for (std::size_t i = 0; i + 1 < cuts.size(); ++i) {
      for (std::size_t m = cuts[i] + 3; m + 3 <= cuts[i + 1]; ++m) {
        std::vector<std::size_t> c = cuts;
        c.insert(c.begin() + static_cast<std::ptrdiff_t>(i) + 1, m);
        const double v = total(c);
        if (v < best) best = v, bestCuts = std::move(c);
      }
    }
    if (bestCuts.empty() || rss - best <= cutGain * sigma * sigma) break;
    cuts = std::move(bestCuts);
    rss = best;
  }
  double dummy = 0.0, sxx = 0.0;
  double rate[2] = {fx.fit(cuts, dummy, sxx), fy.fit(cuts, dummy, sxx)};
  const double sigmaRate = sxx > 0.0 ? sigma / std::sqrt(sxx) : 0.0;
  std::ostringstream s;
  s.precision(3);
  s << cuts.size() - 1 << " pointing(s)";
  const char* axis[2] = {"x", "y"};
  for (int a = 0; a < 2; ++a) {
    if (std::abs(rate[a]) < 3.0 * sigmaRate) {
      s << ", no significant drift along " << axis[a] << " (" << rate[a] << " +- " << sigmaRate
        << " px/s): 0";
      rate[a] = 0.0;
    }
  }
  note = s.str();
  return {rate[0], rate[1]};
}

std::string modelNote(const Registration& r, std::size_t frames) {
  std::ostringstream s;
  s.precision(3);
  switch (r.model) {
    case Registration::Model::Linear:
      s << "registration: the linear sky rate fits the star field of the " << frames
        << " frames (residual rms " << r.rmsPx << " px, max " << r.maxPx << " px";
      if (r.outlierFrames > 0)
        s << "; " << r.outlierFrames
          << " isolated frame(s) departing beyond their measurement error taken for measurement outliers and "
             "kept on the line";
      else if (!r.position.empty())
        s << "; no frame departs from it beyond its measurement error";
      s << ")";
      break;
    case Registration::Model::PerFrame:
      s << "registration: the linear sky rate (" << r.rate.vx << ", " << r.rate.vy
        << ") px/s leaves the star field off by rms " << r.rmsPx << " px, max " << r.maxPx
        << " px (dithers, guiding, re-pointing): per-frame offsets are used for the " << r.significantFrames
        << " frame(s) that depart from it significantly";
      if (!r.rateNote.empty()) s << " (" << r.rateNote << ")";
      break;
    case Registration::Model::Unmeasured:
      s << "registration: the star field could not be followed from frame to frame (" << r.linksMeasured
        << " significant links); the linear sky rate is the model";
      break;
  }
  return s.str();
}

}  // namespace

Registration measureRegistration(const FrameCube& cube, std::optional<Velocity> givenRate,
                                 const RegistrationParams& params, ProgressSink& progress,
                                 CancelToken& cancel, const RegistrationHooks& hooks) {
  Registration r;
  const std::size_t nf = cube.frameCount();
  r.offsets.assign(nf, PixelOffset{});
  if (nf < 3 || cube.width() < 16 || cube.height() < 16) {
    r.note = modelNote(r, nf);
    return r;
  }
  const std::vector<double> dt = cube.timeOffsetsS();
  std::vector<std::size_t> order(nf);
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return dt[a] < dt[b]; });
  const StarImages images(cube, hooks.gate);

  // Long sequences: sampled links first; when they all follow one linear rate, that is the model.
  if (nf > 2 * kQuickFrames) {
    std::vector<Link> quick(kQuickFrames);
    std::vector<std::size_t> at(kQuickFrames);
    for (int i = 0; i < kQuickFrames; ++i)
      at[i] = (nf - 2) * static_cast<std::size_t>(i) / (kQuickFrames - 1);
    // On a device when it takes them (the frames it holds: none read here); the links it did not make, and
    // all of them without one, on the CPU.
    std::vector<char> made(quick.size(), 0);
    if (hooks.links) {
      RegistrationLinkBatch batch;
      batch.bin = images.bin();
      batch.width = images.width();
      batch.height = images.height();
      batch.taperX = &images.weights().taperX;
      batch.taperY = &images.weights().taperY;
      batch.highPass = &images.weights().highPass;
      for (int i = 0; i < kQuickFrames; ++i)
        batch.pairs.emplace_back(order[at[i] + 1], order[at[i]]);
      if (const auto peaks = hooks.links(cube, batch); peaks && peaks->size() == quick.size()) {
        for (std::size_t i = 0; i < quick.size(); ++i)
          if ((*peaks)[i].ok) {
            quick[i] = detail::linkFromPeak(images, (*peaks)[i], params.minPeakSnr);
            made[i] = 1;
          }
      }
    }
    parallelFor(quick.size(), 1, [&](std::size_t b, std::size_t e) {
      for (std::size_t i = b; i < e; ++i) {
        cancel.throwIfCancelled();
        if (!made[i]) quick[i] = measureLink(images, order[at[i] + 1], order[at[i]], params.minPeakSnr);
      }
    });
    r.linksElsewhere = static_cast<int>(std::count(made.begin(), made.end(), 1));
    std::vector<double> rx, ry;
    for (int i = 0; i < kQuickFrames; ++i) {
      const double gap = dt[order[at[i] + 1]] - dt[order[at[i]]];
      if (!quick[i].ok || !(gap > 0.0)) continue;
      rx.push_back(quick[i].step.x / gap);
      ry.push_back(quick[i].step.y / gap);
      ++r.linksMeasured;
    }
    const Velocity rate = givenRate.value_or(Velocity{median(rx), median(ry)});
    double worst = 0.0, sum2 = 0.0;
    // Each significant link within quickTolerancePx, or within its own measurement error. Links without a
    // significant peak (frames with few stars: the paper-neo field that crosses the frame three times in
    // 1500 frames leaves ~25% of its single frames too faint to link) say nothing against the model.
    bool agree = true;
    for (int i = 0; i < kQuickFrames; ++i) {
      const double gap = dt[order[at[i] + 1]] - dt[order[at[i]]];
      if (!quick[i].ok || !(gap > 0.0)) continue;
      const double ex = quick[i].step.x - rate.vx * gap, ey = quick[i].step.y - rate.vy * gap;
      const double e = std::hypot(ex, ey);
      worst = std::max(worst, e);
      sum2 += ex * ex + ey * ey;
      agree = agree && e <= std::max(params.quickTolerancePx, kSignificance * quick[i].sigma);
    }
    const std::string sampled =
        " (" + std::to_string(r.linksMeasured) + " of " + std::to_string(kQuickFrames) +
        " sampled frame pairs significant" +
        (r.linksElsewhere > 0 ? "; " + std::to_string(r.linksElsewhere) + " measured on the device" : "") +
        ")";
    if (r.linksMeasured < kQuickFrames / 2) {  // faint frames (EMCCD at 16.7 Hz): not worth every frame
      r.note = modelNote(r, nf) + sampled;
      return r;
    }
    if (agree) {
      r.model = Registration::Model::Linear;
      r.rate = rate;
      r.rmsPx = std::sqrt(sum2 / r.linksMeasured);
      r.maxPx = worst;
      r.note = modelNote(r, nf) + sampled;
      return r;
    }
    r.linksMeasured = 0;
  }

  // Every frame linked to its predecessor in time (to an earlier one when that link fails).
  std::vector<Link> links(nf);
  std::vector<int> back(nf, 1);
  std::atomic<std::size_t> done{0};
  parallelFor(nf - 1, 1, [&](std::size_t b, std::size_t e) {
    for (std::size_t k = b + 1; k < e + 1; ++k) {
      cancel.throwIfCancelled();
      for (int d = 1; d <= kMaxBack && d <= static_cast<int>(k); ++d) {
        links[k] = measureLink(images, order[k], order[k - d], params.minPeakSnr);
        back[k] = d;
        if (links[k].ok) break;
      }
      progress.report(static_cast<double>(done.fetch_add(1) + 1) / static_cast<double>(nf - 1),
                      "registration");
    }
  });
  std::vector<double> px(nf, 0.0), py(nf, 0.0), t(nf, 0.0);
  std::vector<double> lrx, lry;  // rates of the significant links
  for (std::size_t k = 0; k < nf; ++k) {
    t[k] = dt[order[k]];
    if (k == 0 || !links[k].ok) continue;
    ++r.linksMeasured;
    const double gap = dt[order[k]] - dt[order[k - back[k]]];
    if (gap > 0.0) lrx.push_back(links[k].step.x / gap), lry.push_back(links[k].step.y / gap);
  }
  if (r.linksMeasured < static_cast<int>(nf - 1) / 2 || lrx.empty()) {  // too faint to follow
    r.note = modelNote(r, nf);
    return r;
  }
  // A frame no link reaches is bridged from its predecessor at the links' median rate, with an error of
  // kBridgeSigmaPx: the anchor pass below re-measures the frames after it within that error (a dither hidden
  // in the bridge is found there), and a frame it cannot measure either keeps the linear model (o_n = 0).
  const Velocity bridgeRate{median(lrx), median(lry)};
  std::size_t bridged = 0;
  for (std::size_t k = 1; k < nf; ++k) {
    if (!links[k].ok) {
      const double gap = t[k] - t[k - 1];
      links[k].step = {bridgeRate.vx * gap, bridgeRate.vy * gap};
      links[k].sigma = kBridgeSigmaPx;
      back[k] = 1;
      ++bridged;
    }
    px[k] = px[k - back[k]] + links[k].step.x;
    py[k] = py[k - back[k]] + links[k].step.y;
  }
  // Second pass, against anchors: every frame measured directly against the last anchor frame whose field it
  // still largely shares (chained positions within 0.4 of the frame), anchors linked to each other,
  // so the errors of the neighbour chain do not add up over the whole sequence (sidereal data: one anchor).
  const double reach = 0.4 * std::min(cube.width(), cube.height());
  std::vector<std::size_t> anchorOf(nf, 0);
  std::vector<std::size_t> anchors{0};
  for (std::size_t k = 1; k < nf; ++k) {
    const std::size_t a = anchors.back();
    if (std::hypot(px[k] - px[a], py[k] - py[a]) > reach) anchors.push_back(k - 1);
    anchorOf[k] = anchors.back();
  }
  // anchorOf[k] < k: an anchor frame itself is measured against the anchor before it.
  std::vector<Link> direct(nf);
  std::vector<double> posVar(nf, 0.0);  ///< variance of P_k (per axis, px^2) from the links that gave it
  // Variance of the chained position (per axis) and of the chained step between two frames: along the
  // back-pointer tree, through the frames' common ancestor.
  std::vector<double> chainVar(nf, 0.0);
  for (std::size_t k = 1; k < nf; ++k)
    chainVar[k] = chainVar[k - back[k]] + links[k].sigma * links[k].sigma;
  const auto chainStepVar = [&](std::size_t i, std::size_t j) {
    std::size_t a = i, b = j;
    while (a != b) {
      if (a > b) {
        a -= static_cast<std::size_t>(back[a]);
      } else {
        b -= static_cast<std::size_t>(back[b]);
      }
    }
    return std::max(0.0, chainVar[i] + chainVar[j] - 2.0 * chainVar[a]);
  };
  parallelFor(nf - 1, 1, [&](std::size_t b, std::size_t e) {
    for (std::size_t k = b + 1; k < e + 1; ++k) {
      cancel.throwIfCancelled();
      const std::size_t ref = anchorOf[k];
      if (ref + back[k] == k) {
        direct[k] = links[k];
        continue;
      }
      // Guided by the chained step: within 3 px plus 4 sigma of the chain between the two frames plus 2% of
      // the distance; a best pixel on the disk's rim is not taken (the link falls back to the chain).
      const PixelOffset chained{px[k] - px[ref], py[k] - py[ref]};
      const double radius =
          3.0 + 4.0 * std::sqrt(2.0 * chainStepVar(k, ref)) + 0.02 * std::hypot(chained.x, chained.y);
      direct[k] = measureLink(images, order[k], order[ref], params.minPeakSnr, chained, radius);
    }
  });
  {
    std::vector<double> qx(px), qy(py);
    for (std::size_t k = 1; k < nf; ++k) {
      const std::size_t ref = anchorOf[k];
      if (direct[k].ok) {
        qx[k] = qx[ref] + direct[k].step.x;
        qy[k] = qy[ref] + direct[k].step.y;
        posVar[k] = posVar[ref] + direct[k].sigma * direct[k].sigma;
      } else {  // the chained step from the anchor
        qx[k] = qx[ref] + (px[k] - px[ref]);
        qy[k] = qy[ref] + (py[k] - py[ref]);
        posVar[k] = posVar[ref] + chainStepVar(k, ref);
      }
    }
    px = std::move(qx);
    py = std::move(qy);
  }
  const std::size_t gapPairs = std::max<std::size_t>(1, nf / 4);
  r.position.assign(nf, PixelOffset{});
  for (std::size_t k = 0; k < nf; ++k)
    r.position[order[k]] = {px[k], py[k]};
  // Residuals from a rate, o_0 = 0 (frame 0 keeps the WCS's mapping); rms about their own mean (a constant
  // offset is no departure from a linear motion), largest.
  std::vector<PixelOffset> resid(nf);
  const auto residuals = [&](Velocity rate) {
    double mx = 0.0, my = 0.0;
    r.maxPx = 0.0;
    for (std::size_t k = 0; k < nf; ++k) {
      const PixelOffset o{px[k] - rate.vx * (t[k] - t[0]), py[k] - rate.vy * (t[k] - t[0])};
      resid[order[k]] = o;
      mx += o.x / static_cast<double>(nf), my += o.y / static_cast<double>(nf);
    }
    double var = 0.0;
    for (const auto& o : resid) {
      var += (o.x - mx) * (o.x - mx) + (o.y - my) * (o.y - my);
      r.maxPx = std::max(r.maxPx, std::hypot(o.x - mx, o.y - my));
    }
    r.rmsPx = std::sqrt(var / static_cast<double>(nf));
  };
  r.rate = givenRate.value_or(Velocity{theilSen(t, px, gapPairs), theilSen(t, py, gapPairs)});
  residuals(r.rate);
  if (r.rmsPx > params.linearRmsPx && !givenRate) {
    r.rate = robustRate(t, px, py, r.rateNote);
    residuals(r.rate);
  }
  // Per-frame offsets only where the departure from the linear model is significant against the frame's
  // own measurement error (kSignificance sigma, propagated along the links that placed it): frames whose
  // star field is faint or changing are measured at low peak significance, and their scatter is no
  // pointing jump (paper-neo seed 25: links at SNR 8-12 in its first 40 frames gave rms 1.8 px of false
  // "pointings"). Insignificant departures keep the linear model (o_n = 0).
  std::size_t significant = 0;
  std::vector<std::uint8_t> departs(nf, 0);  // time order
  for (std::size_t k = 0; k < nf; ++k) {
    PixelOffset& o = resid[order[k]];
    // |o| of two axes, each of variance posVar: its scale is sqrt(2 posVar).
    if (std::hypot(o.x, o.y) > kSignificance * std::sqrt(2.0 * posVar[k])) {
      ++significant;
      departs[k] = 1;
    } else {
      o = {};
    }
  }
  r.significantFrames = static_cast<int>(significant);
  // A few isolated frames of a long sequence (at most 1 in 100, neither time neighbour departing) are taken
  // for measurement outliers of a linear field, not pointings (robustRate's pointings hold >= 3 frames; a
  // dither or nod pattern moves many frames): paper-neo seed 52 (500 frames) had one star-poor frame's link
  // 0.7 px off the truth at SNR ~20, and the per-frame model's two pointings put the rate 0.012 px/s off.
  bool outliersOnly = significant > 0 && significant * 100 <= nf;
  for (std::size_t k = 0; outliersOnly && k < nf; ++k)
    if (departs[k] && ((k > 0 && departs[k - 1]) || (k + 1 < nf && departs[k + 1]))) outliersOnly = false;
  if (outliersOnly) {
    for (auto& o : resid)
      o = {};
    r.outlierFrames = static_cast<int>(significant);
  }
  if (r.rmsPx <= params.linearRmsPx || significant == 0 || outliersOnly) {
    r.model = Registration::Model::Linear;
  } else {
    r.model = Registration::Model::PerFrame;
    r.offsets = std::move(resid);
  }
  r.note = modelNote(r, nf);
  if (bridged > 0)
    r.note += "; " + std::to_string(bridged) +
              " frame(s) without a significant link to the 3 before placed at "
              "the links' median rate";
  return r;
}

void applyRegistration(FrameCube& cube, const Registration& reg) {
  auto& info = cube.info();
  const bool use = reg.model == Registration::Model::PerFrame && reg.offsets.size() == info.size();
  for (std::size_t n = 0; n < info.size(); ++n) {
    info[n].offsetXPx = use ? reg.offsets[n].x : 0.0;
    info[n].offsetYPx = use ? reg.offsets[n].y : 0.0;
  }
}

namespace {

/// Moves the content of frame n by -sign * shift[n] (new(x, y) = old(x + sign sx, y + sign sy) where that
/// lies in the frame; elsewhere 0 and masked when the cube has a mask). Returns the frames moved.
std::size_t shiftFrames(FrameCube& cube, const std::vector<std::pair<int, int>>& shift, int sign,
                        CancelToken& cancel) {
  const std::size_t nf = cube.frameCount();
  const int w = cube.width(), h = cube.height();
  const std::size_t np = cube.framePixels();
  const bool masked = cube.mask().size() == cube.pixels().size();
  std::atomic<std::size_t> moved{0};
  parallelFor(nf, 1, [&](std::size_t b, std::size_t e) {
    std::vector<float> pix(np);
    std::vector<std::uint8_t> msk(masked ? np : 0);
    for (std::size_t n = b; n < e; ++n) {
      const int sx = sign * shift[n].first, sy = sign * shift[n].second;
      if (sx == 0 && sy == 0) continue;
      cancel.throwIfCancelled();
      float* f = cube.frame(n);
      std::uint8_t* m = masked ? cube.mask().data() + n * np : nullptr;
      std::fill(pix.begin(), pix.end(), 0.0f);
      std::fill(msk.begin(), msk.end(), std::uint8_t{1});
      const int x0 = std::max(0, -sx), x1 = std::min(w, w - sx);
      for (int y = std::max(0, -sy); y < std::min(h, h - sy); ++y) {
        if (x1 <= x0) break;
        const std::size_t dst = static_cast<std::size_t>(y) * w + x0;
        const std::size_t src = static_cast<std::size_t>(y + sy) * w + x0 + sx;
        std::copy_n(f + src, x1 - x0, pix.data() + dst);
        if (m) std::copy_n(m + src, x1 - x0, msk.data() + dst);
      }
      std::copy(pix.begin(), pix.end(), f);
      if (m) std::copy(msk.begin(), msk.end(), m);
      moved.fetch_add(1);
    }
  });
  return moved.load();
}

}  // namespace

std::size_t alignWholePixels(FrameCube& cube, Registration& reg, CancelToken& cancel) {
  const std::size_t nf = cube.frameCount();
  if (reg.model != Registration::Model::PerFrame || reg.offsets.size() != nf) return 0;
  std::vector<std::pair<int, int>> shift(nf);
  bool any = false;
  for (std::size_t n = 0; n < nf; ++n) {
    shift[n] = {static_cast<int>(std::lround(reg.offsets[n].x)),
                static_cast<int>(std::lround(reg.offsets[n].y))};
    any = any || shift[n].first != 0 || shift[n].second != 0;
  }
  if (!any) return 0;
  // new(x, y) = old(x + sx, y + sy): the uncovered pixels masked.
  if (cube.mask().empty()) cube.mask().assign(cube.framePixels() * nf, 0);
  const std::size_t moved = shiftFrames(cube, shift, 1, cancel);
  for (std::size_t n = 0; n < nf; ++n) {
    reg.offsets[n].x -= shift[n].first;
    reg.offsets[n].y -= shift[n].second;
  }
  reg.alignedPx = std::move(shift);
  return moved;
}

void restoreWholePixels(FrameCube& cube, const Registration& reg, CancelToken& cancel) {
  if (reg.alignedPx.empty()) return;
  const std::size_t nf = cube.frameCount();
  if (reg.alignedPx.size() != nf || cube.info().size() != nf)
    throw InputError("registration: " + std::to_string(reg.alignedPx.size()) + " whole-pixel shifts for " +
                     std::to_string(nf) + " frames");
  shiftFrames(cube, reg.alignedPx, -1, cancel);
  for (std::size_t n = 0; n < nf; ++n) {
    cube.info()[n].offsetXPx += reg.alignedPx[n].first;
    cube.info()[n].offsetYPx += reg.alignedPx[n].second;
  }
}

std::vector<std::uint32_t> alignedCoverage(const Registration& reg, int width, int height) {
  if (reg.alignedPx.empty()) return {};
  // Per row, the covered columns of each frame as a difference array.
  std::vector<std::uint32_t> out(static_cast<std::size_t>(width) * height, 0);
  std::vector<int> diff(static_cast<std::size_t>(width) + 1);
  for (int y = 0; y < height; ++y) {
    std::fill(diff.begin(), diff.end(), 0);
    for (const auto& [sx, sy] : reg.alignedPx) {
      if (y + sy < 0 || y + sy >= height) continue;
      const int lo = std::clamp(-sx, 0, width), hi = std::clamp(width - sx, lo, width);
      ++diff[static_cast<std::size_t>(lo)];
      --diff[static_cast<std::size_t>(hi)];
    }
    int c = 0;
    for (int x = 0; x < width; ++x)
      out[static_cast<std::size_t>(y) * width + x] =
          static_cast<std::uint32_t>(c += diff[static_cast<std::size_t>(x)]);
  }
  return out;
}

}  // namespace st::detect

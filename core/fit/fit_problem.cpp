#include "fit_problem.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <unordered_map>

#include "st/common/parallel.hpp"
#include "st/fit/pixel_psf.hpp"

namespace st::fit::detail {

FitProblem::FitProblem(const FrameCube& cube, std::vector<std::size_t> frames, std::vector<double> times,
                       const psf::Moffat& psf, int halfSize)
    : m_cube(cube),
      m_frames(std::move(frames)),
      m_times(std::move(times)),
      m_cx(m_frames.size(), 0),
      m_cy(m_frames.size(), 0),
      m_psf(psf),
      m_table(psf, 2.0 * halfSize + 4.0),
      m_half(halfSize),
      m_clipLevel(std::numeric_limits<double>::infinity()),
      m_termStart(m_frames.size() + 1, 0) {
  // The frames' registration offsets: the track in frame n is at (xc + ox_n + vx t, yc + oy_n + vy t).
  for (const std::size_t n : m_frames) {
    m_ox.push_back(n < cube.frameCount() ? cube.info()[n].offsetXPx : 0.0);
    m_oy.push_back(n < cube.frameCount() ? cube.info()[n].offsetYPx : 0.0);
  }
}

void FitProblem::setSelfSubtraction(const stats::PixelBackgroundWindows& windows, double tRefOffsetS,
                                    double clipLevel, bool sourceInBackground) {
  m_windows = windows.empty() ? nullptr : &windows;
  m_termsOn = sourceInBackground;
  m_tRefOffsetS = tRefOffsetS;
  m_clipLevel = clipLevel;
  // A term farther than 3 FWHM (+ 1 px) from a pixel adds < 2e-3 of the peak even for beta = 2.5.
  const double reach = 3.0 * m_psf.fwhm() + 1.0;
  m_termReach2 = reach * reach;
}

void FitProblem::centreStamps(const FitParams& p) {
  for (std::size_t k = 0; k < m_frames.size(); ++k) {
    m_cx[k] = static_cast<int>(std::lround(p.xc + m_ox[k] + p.v.vx * m_times[k]));
    m_cy[k] = static_cast<int>(std::lround(p.yc + m_oy[k] + p.v.vy * m_times[k]));
  }
  gatherBackgroundTerms(p);
}

void FitProblem::gatherBackgroundTerms(const FitParams& p) {
  m_terms.clear();
  m_termStart.assign(m_frames.size() + 1, 0);
  if (m_windows == nullptr || !m_termsOn) return;
  const std::vector<double> t = m_cube.timeOffsetsS();
  const auto& info = m_cube.info();
  const std::vector<std::size_t>& used = m_windows->frames;
  const double groupSpan = m_psf.fwhm() / 8.0;
  // Terms whose track position is farther than this from the stamp's centre reach none of its pixels, even
  // after the track moves by a stamp's half-size during the fit (re-centring gathers them again).
  const double reach = std::sqrt(m_termReach2) + 2.5 * m_half + 1.0;
  const auto at = [&](std::size_t m) {
    return std::array<double, 2>{p.xc + info[m].offsetXPx + p.v.vx * (t[m] - m_tRefOffsetS),
                                 p.yc + info[m].offsetYPx + p.v.vy * (t[m] - m_tRefOffsetS)};
  };
  for (std::size_t k = 0; k < m_frames.size(); ++k) {
    m_termStart[k] = m_terms.size();
    const auto [lo, hi] = m_windows->leftOut(m_frames[k], t);
    const double w = 1.0 / static_cast<double>(used.size() - (hi - lo));
    const double cx = p.xc + m_ox[k] + p.v.vx * m_times[k];
    const double cy = p.yc + m_oy[k] + p.v.vy * m_times[k];
    // The frames of the background in two runs (before and after the left-out range), each cut into groups
    // whose track positions lie within groupSpan of each other.
    for (const auto& [b, e] : {std::pair{std::size_t{0}, lo}, std::pair{hi, used.size()}}) {
      std::size_t g = b;
      while (g < e) {
        const auto first = at(used[g]);
        double x0 = first[0], x1 = first[0], y0 = first[1], y1 = first[1];
        double st = 0.0, sx = 0.0, sy = 0.0;
        std::size_t c = 0;
        for (; g < e; ++g, ++c) {
          const auto r = at(used[g]);
          const double nx0 = std::min(x0, r[0]), nx1 = std::max(x1, r[0]);
          const double ny0 = std::min(y0, r[1]), ny1 = std::max(y1, r[1]);
          if (c > 0 && (nx1 - nx0 > groupSpan || ny1 - ny0 > groupSpan)) break;
          x0 = nx0, x1 = nx1, y0 = ny0, y1 = ny1;
          st += t[used[g]] - m_tRefOffsetS;
          sx += info[used[g]].offsetXPx;
          sy += info[used[g]].offsetYPx;
        }
        const double n = static_cast<double>(c);
        const BackgroundTerm term{st / n, sx / n, sy / n, w * n};
        const double dx = p.xc + term.ox + p.v.vx * term.t - cx;
        const double dy = p.yc + term.oy + p.v.vy * term.t - cy;
        if (dx * dx + dy * dy <= reach * reach) m_terms.push_back(term);
      }
    }
  }
  m_termStart[m_frames.size()] = m_terms.size();
}

FitProblem::ModelSample FitProblem::modelSample(std::size_t k, int x, int y,
                                                const FitParams& p) const noexcept {
  const double t = m_times[k];
  const PsfSample s = m_table.sample(x - (p.xc + m_ox[k] + p.v.vx * t), y - (p.yc + m_oy[k] + p.v.vy * t));
  ModelSample m{s.value, s.value, t * s.du, t * s.dv, s.du, s.dv};
  for (std::size_t i = m_termStart[k]; i < m_termStart[k + 1]; ++i) {
    const BackgroundTerm& g = m_terms[i];
    const double u = x - (p.xc + g.ox + p.v.vx * g.t);
    const double v = y - (p.yc + g.oy + p.v.vy * g.t);
    if (u * u + v * v > m_termReach2) continue;
    const PsfSample b = m_table.sample(u, v);
    if (p.alpha * b.value > m_clipLevel) continue;  // the clip left this sample out of the background
    m.value -= g.w * b.value;
    m.atDu -= g.w * g.t * b.du;
    m.atDv -= g.w * g.t * b.dv;
    m.du -= g.w * b.du;
    m.dv -= g.w * b.dv;
  }
  return m;
}

int FitProblem::centreDrift(const FitParams& p) const {
  double drift = 0.0;
  for (std::size_t k = 0; k < m_frames.size(); ++k) {
    drift = std::max(drift, std::abs(std::round(p.xc + m_ox[k] + p.v.vx * m_times[k]) - m_cx[k]));
    drift = std::max(drift, std::abs(std::round(p.yc + m_oy[k] + p.v.vy * m_times[k]) - m_cy[k]));
  }
  return drift > 1e6 ? 1000000 : static_cast<int>(drift);
}

std::size_t FitProblem::framesInside(const FitParams& p) const {
  std::size_t n = 0;
  for (std::size_t k = 0; k < m_times.size(); ++k) {
    const double t = m_times[k];
    const double x = p.xc + m_ox[k] + p.v.vx * t;
    const double y = p.yc + m_oy[k] + p.v.vy * t;
    if (x >= -0.5 && y >= -0.5 && x < m_cube.width() - 0.5 && y < m_cube.height() - 0.5) ++n;
  }
  return n;
}

// Calls fn(x, y, value) for every unmasked in-frame pixel of stamp k.
template <typename PixelFn>
void FitProblem::forEachPixel(std::size_t k, const PixelFn& fn) const {
  const std::size_t n = m_frames[k];
  const float* img = m_cube.frame(n);
  const int w = m_cube.width();
  const int x0 = std::max(0, m_cx[k] - m_half);
  const int x1 = std::min(w - 1, m_cx[k] + m_half);
  const int y0 = std::max(0, m_cy[k] - m_half);
  const int y1 = std::min(m_cube.height() - 1, m_cy[k] + m_half);
  for (int y = y0; y <= y1; ++y) {
    for (int x = x0; x <= x1; ++x) {
      if (m_cube.isMasked(n, x, y)) continue;
      const float d = img[static_cast<std::size_t>(y) * w + x];
      if (!std::isfinite(d)) continue;
      fn(x, y, static_cast<double>(d));
    }
  }
}

NormalEquations FitProblem::evaluate(const FitParams& p, bool withJacobian) const {
  const std::size_t nf = m_frames.size();
  const std::size_t chunk = std::max<std::size_t>(1, nf / (8 * workerCount()) + 1);
  const std::size_t nChunks = (nf + chunk - 1) / chunk;
  std::vector<NormalEquations> partial(nChunks);
  parallelFor(nf, chunk, [&](std::size_t b, std::size_t e) {
    NormalEquations& acc = partial[b / chunk];
    ParamVector j;
    for (std::size_t k = b; k < e; ++k) {
      forEachPixel(k, [&](int x, int y, double d) {
        const ModelSample s = modelSample(k, x, y, p);
        const double r = d - (p.alpha * s.value + p.i0);
        acc.cost += r * r;
        ++acc.pixels;
        if (!withJacobian) return;
        // model = alpha P(x - xc - vx t, y - yc - vy t) + I0 (less its background terms)
        j << -p.alpha * s.atDu, -p.alpha * s.atDv, -p.alpha * s.du, -p.alpha * s.dv, s.value, 1.0;
        acc.jtj.selfadjointView<Eigen::Lower>().rankUpdate(j);
        acc.jtr.noalias() += j * r;
      });
    }
  });
  NormalEquations total;
  for (const auto& a : partial) {
    total.jtj += a.jtj;
    total.jtr += a.jtr;
    total.cost += a.cost;
    total.pixels += a.pixels;
  }
  const ParamMatrix full = total.jtj.selfadjointView<Eigen::Lower>();
  total.jtj = full;
  return total;
}

ParamMatrix FitProblem::noiseMoment(const FitParams& p, double sigmaN2, double gain) const {
  ParamMatrix m = ParamMatrix::Zero();
  // Frame n's background is the mean of its frames O_n, so the zero-biased frames' noise at one pixel is
  // correlated: d_n = e_n - sum_m a_n(m) e_m, a_n(m) = 1 / |O_n| for m in O_n, and cov(d_n, d_n') =
  // sigma_n^2 (delta - a_n(n') - a_n'(n) + |O_n & O_n'| / (|O_n| |O_n'|)). A slow mover's stamps share
  // pixels across frames, so every pair sharing a pixel adds to the middle of the sandwich (pixelMoment
  // sums them exactly); without the windows only the diagonal is known.
  const NoiseCorrelation corr = noiseCorrelation();
  std::unordered_map<std::size_t, std::vector<PixelSample>> byPixel;
  for (std::size_t k = 0; k < m_frames.size(); ++k) {
    forEachPixel(k, [&](int x, int y, double) {
      const ModelSample s = modelSample(k, x, y, p);
      ParamVector j;
      j << -p.alpha * s.atDu, -p.alpha * s.atDv, -p.alpha * s.du, -p.alpha * s.dv, s.value, 1.0;
      // The source's photon noise is this frame's; its background terms' is averaged away.
      const double photon = std::max(p.alpha * s.own, 0.0) / gain;
      if (corr.empty()) {
        m.selfadjointView<Eigen::Lower>().rankUpdate(j, sigmaN2 + photon);
        return;
      }
      m.selfadjointView<Eigen::Lower>().rankUpdate(j, photon);
      byPixel[static_cast<std::size_t>(y) * m_cube.width() + x].push_back({k, j});
    });
  }
  for (auto& [pixel, list] : byPixel)
    m.noalias() += sigmaN2 * corr.pixelMoment(list);
  const ParamMatrix full = m.selfadjointView<Eigen::Lower>();
  return full;
}

FitProblem::NoiseCorrelation FitProblem::noiseCorrelation() const {
  NoiseCorrelation c;
  if (m_windows == nullptr) return c;
  const std::vector<double> t = m_cube.timeOffsetsS();
  const std::vector<std::size_t>& used = m_windows->frames;
  c.total = used.size();
  for (const std::size_t n : m_frames) {
    const auto [lo, hi] = m_windows->leftOut(n, t);
    const auto it = std::lower_bound(used.begin(), used.end(), n);
    c.lo.push_back(lo);
    c.hi.push_back(hi);
    c.pos.push_back(it != used.end() && *it == n ? static_cast<std::size_t>(it - used.begin()) : kNone);
  }
  return c;
}

ParamMatrix FitProblem::NoiseCorrelation::pixelMoment(std::vector<PixelSample>& list) const {
  // sum_{k,k'} K(k, k') j_k j_k'^T = sum_k j_k j_k^T - sum_k (j_k s_k^T + s_k j_k^T) + sum_m b_m b_m^T, with
  // s_k = sum_k' a_k(frame of k') j_k' (from prefix sums over the samples' places in the background's
  // frames) and b_m = sum_k a_k(m) j_k (piecewise constant in m between the samples' left-out ranges):
  // O(M log M) for the M samples of a pixel instead of M^2 pairs.
  ParamMatrix out = ParamMatrix::Zero();
  std::sort(list.begin(), list.end(),
            [&](const PixelSample& a, const PixelSample& b) { return pos[a.k] < pos[b.k]; });
  std::vector<ParamVector> prefix(list.size() + 1, ParamVector::Zero());
  std::vector<std::size_t> places;
  places.reserve(list.size());
  std::size_t inBackground = 0;
  for (const PixelSample& e : list) {
    if (pos[e.k] == kNone) break;
    prefix[inBackground + 1] = prefix[inBackground] + e.j;
    places.push_back(pos[e.k]);
    ++inBackground;
  }
  const auto sumWithin = [&](std::size_t from, std::size_t to) {  // sum of j over places in [from, to)
    const auto a = std::lower_bound(places.begin(), places.end(), from) - places.begin();
    const auto b = std::lower_bound(places.begin(), places.end(), to) - places.begin();
    return ParamVector(prefix[b] - prefix[a]);
  };
  ParamVector t = ParamVector::Zero();
  std::vector<std::pair<std::size_t, ParamVector>> events;  // (place, change of the left-out sum w_m)
  for (const PixelSample& e : list) {
    const std::size_t k = e.k;
    const double size = static_cast<double>(total - (hi[k] - lo[k]));
    const ParamVector s = (prefix[inBackground] - sumWithin(lo[k], hi[k])) / size;
    out.noalias() += e.j * e.j.transpose() - e.j * s.transpose() - s * e.j.transpose();
    const ParamVector g = e.j / size;
    t += g;
    if (hi[k] > lo[k]) {
      events.emplace_back(lo[k], g);
      events.emplace_back(hi[k], -g);
    }
  }
  std::sort(events.begin(), events.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  ParamVector w = ParamVector::Zero();
  std::size_t at = 0;
  for (std::size_t i = 0; i <= events.size(); ++i) {
    const std::size_t next = i < events.size() ? events[i].first : total;
    if (next > at) {
      const ParamVector b = t - w;
      out.noalias() += static_cast<double>(next - at) * (b * b.transpose());
      at = next;
    }
    if (i < events.size()) w += events[i].second;
  }
  return out;
}

FitProblem::LinearSums FitProblem::linearSums(const FitParams& p) const {
  LinearSums l;
  for (std::size_t k = 0; k < m_frames.size(); ++k) {
    forEachPixel(k, [&](int x, int y, double d) {
      const ModelSample s = modelSample(k, x, y, p);
      const double v = s.value;
      l.sep += v * s.own;
      l.sPP += s.own * s.own;
      l.sp += v;
      l.spp += v * v;
      l.sd += d;
      l.sdp += d * v;
      l.n += 1;
    });
  }
  return l;
}

double FitProblem::snrKept(const FitParams& p) const {
  if (m_terms.empty()) return 1.0;
  const LinearSums l = linearSums(p);
  return l.sPP > 0.0 ? l.sep / l.sPP : 1.0;
}

FitParams FitProblem::linearAmplitude(const FitParams& p, bool fitI0) const {
  return linearAmplitude(p, fitI0, linearSums(p));
}

FitParams FitProblem::linearAmplitude(const FitParams& p, bool fitI0, const LinearSums& l) {
  FitParams out = p;
  if (fitI0) {
    const double det = l.spp * l.n - l.sp * l.sp;
    if (det > 0) {
      out.alpha = (l.sdp * l.n - l.sp * l.sd) / det;
      out.i0 = (l.spp * l.sd - l.sp * l.sdp) / det;
    }
  } else if (l.spp > 0) {
    out.alpha = (l.sdp - p.i0 * l.sp) / l.spp;
  }
  if (!std::isfinite(out.alpha)) out.alpha = 0.0;
  if (!std::isfinite(out.i0)) out.i0 = p.i0;
  return out;
}

void FitProblem::stacks(const FitParams& p, Image& data, Image& model, Image& residual) const {
  const int side = 2 * m_half + 1;
  data = Image(side, side);
  model = Image(side, side);
  residual = Image(side, side);
  for (std::size_t k = 0; k < m_frames.size(); ++k) {
    const double px = p.xc + m_ox[k] + p.v.vx * m_times[k];
    const double py = p.yc + m_oy[k] + p.v.vy * m_times[k];
    const int ox = static_cast<int>(std::lround(px)) - m_half;
    const int oy = static_cast<int>(std::lround(py)) - m_half;
    const float* img = m_cube.frame(m_frames[k]);
    for (int sy = 0; sy < side; ++sy) {
      for (int sx = 0; sx < side; ++sx) {
        const int x = ox + sx;
        const int y = oy + sy;
        if (x < 0 || y < 0 || x >= m_cube.width() || y >= m_cube.height()) continue;
        if (m_cube.isMasked(m_frames[k], x, y)) continue;
        const double d = img[static_cast<std::size_t>(y) * m_cube.width() + x];
        if (!std::isfinite(d)) continue;
        const double m = p.alpha * modelSample(k, x, y, p).value + p.i0;
        data.at(sx, sy) += static_cast<float>(d);
        model.at(sx, sy) += static_cast<float>(m);
        residual.at(sx, sy) += static_cast<float>(d - m);
      }
    }
  }
}

}  // namespace st::fit::detail

#include "fit_problem.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>

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
      m_half(halfSize) {
  // The frames' registration offsets: the track in frame n is at (xc + ox_n + vx t, yc + oy_n + vy t).
  for (const std::size_t n : m_frames) {
    m_ox.push_back(n < cube.frameCount() ? cube.info()[n].offsetXPx : 0.0);
    m_oy.push_back(n < cube.frameCount() ? cube.info()[n].offsetYPx : 0.0);
  }
}

void FitProblem::centreStamps(const FitParams& p) {
  for (std::size_t k = 0; k < m_frames.size(); ++k) {
    m_cx[k] = static_cast<int>(std::lround(p.xc + m_ox[k] + p.v.vx * m_times[k]));
    m_cy[k] = static_cast<int>(std::lround(p.yc + m_oy[k] + p.v.vy * m_times[k]));
  }
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
      const double t = m_times[k];
      const double px = p.xc + m_ox[k] + p.v.vx * t;
      const double py = p.yc + m_oy[k] + p.v.vy * t;
      forEachPixel(k, [&](int x, int y, double d) {
        const PsfSample s = m_table.sample(x - px, y - py);
        const double r = d - (p.alpha * s.value + p.i0);
        acc.cost += r * r;
        ++acc.pixels;
        if (!withJacobian) return;
        // model = alpha P(x - xc - vx t, y - yc - vy t) + I0
        j << -p.alpha * t * s.du, -p.alpha * t * s.dv, -p.alpha * s.du, -p.alpha * s.dv, s.value, 1.0;
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
  ParamVector j;
  for (std::size_t k = 0; k < m_frames.size(); ++k) {
    const double t = m_times[k];
    const double px = p.xc + m_ox[k] + p.v.vx * t;
    const double py = p.yc + m_oy[k] + p.v.vy * t;
    forEachPixel(k, [&](int x, int y, double) {
      const PsfSample s = m_table.sample(x - px, y - py);
      const double var = sigmaN2 + std::max(p.alpha * s.value, 0.0) / gain;
      j << -p.alpha * t * s.du, -p.alpha * t * s.dv, -p.alpha * s.du, -p.alpha * s.dv, s.value, 1.0;
      m.selfadjointView<Eigen::Lower>().rankUpdate(j, var);
    });
  }
  const ParamMatrix full = m.selfadjointView<Eigen::Lower>();
  return full;
}

FitProblem::LinearSums FitProblem::linearSums(const FitParams& p) const {
  LinearSums l;
  for (std::size_t k = 0; k < m_frames.size(); ++k) {
    const double px = p.xc + m_ox[k] + p.v.vx * m_times[k];
    const double py = p.yc + m_oy[k] + p.v.vy * m_times[k];
    forEachPixel(k, [&](int x, int y, double d) {
      const double v = m_table.value(x - px, y - py);
      l.sp += v;
      l.spp += v * v;
      l.sd += d;
      l.sdp += d * v;
      l.n += 1;
    });
  }
  return l;
}

FitParams FitProblem::linearAmplitude(const FitParams& p, bool fitI0) const {
  const LinearSums l = linearSums(p);
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
        const double m = p.alpha * m_table.value(x - px, y - py) + p.i0;
        data.at(sx, sy) += static_cast<float>(d);
        model.at(sx, sy) += static_cast<float>(m);
        residual.at(sx, sy) += static_cast<float>(d - m);
      }
    }
  }
}

}  // namespace st::fit::detail

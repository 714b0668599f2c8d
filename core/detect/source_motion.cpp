#include "source_motion.hpp"

#include <algorithm>
#include <cmath>

#include "st/detect/sky_stack.hpp"

namespace st::detect::detail {
namespace {

constexpr double kMinThirdFluxSnr = 5.0;  // a third must see the source this well to locate it

double median(std::vector<double> v) {
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

}  // namespace

std::vector<SkyStackCache::Range> thirdRanges(std::size_t frames) {
  const std::size_t third = frames / 3;
  if (third < 2) return {};
  return {{0, third}, {third, frames - third}, {frames - third, frames}};
}

ThirdStacks thirdStacks(const FrameCube& cube, Velocity skyRate, double background, int meshPx,
                        SkyStackCache& stacks, CancelToken& cancel) {
  ThirdStacks out;
  const std::vector<SkyStackCache::Range> ranges = thirdRanges(cube.frameCount());
  if (ranges.empty()) return out;
  const std::size_t bounds[4] = {ranges[0].first, ranges[1].first, ranges[2].first, ranges[2].second};
  const std::vector<double> dt = cube.timeOffsetsS();
  NullProgress none;
  for (int k = 0; k < 3; ++k) {
    const SkyStack& s = stacks.stack(cube, skyRate, background, none, cancel, bounds[k], bounds[k + 1]);
    const Image local = meshBackground(s.mean, s.count, meshPx);
    out.resid[k] = residualWhereCounted(s.mean, s.count, local);
    out.count[k] = s.count;
    out.frames[k] = static_cast<int>(bounds[k + 1] - bounds[k]);
    const double nk = out.frames[k];
    for (std::size_t f = bounds[k]; f < bounds[k + 1]; ++f) {
      out.meanTimeS[k] += dt[f] / nk;
      const FrameInfo& fi = cube.info()[f];
      const double sx = fi.offsetXPx + skyRate.vx * dt[f], sy = fi.offsetYPx + skyRate.vy * dt[f];
      out.residualX[k] += (sx - static_cast<double>(std::lround(sx))) / nk;
      out.residualY[k] += (sy - static_cast<double>(std::lround(sy))) / nk;
    }
  }
  return out;
}

SourceShift measureShift(const std::vector<int>& comp, int cw, const ThirdStacks& thirds, double sigma) {
  SourceShift out;
  if (!thirds.valid() || comp.empty() || sigma <= 0) return out;
  for (int k = 0; k < 3; ++k) {
    const Image& resid = thirds.resid[k];
    const Image& count = thirds.count[k];
    double sw = 0.0, sx = 0.0, sy = 0.0, sv = 0.0;
    for (int p : comp) {
      if (count.pixels[p] < thirds.frames[k]) return out;  // partly seen: at an edge
      const double v = resid.pixels[p];
      sw += v;
      sx += v * (p % cw);
      sy += v * (p / cw);
      sv += sigma * sigma / count.pixels[p];
    }
    if (sw <= 0 || sw / std::sqrt(sv) < kMinThirdFluxSnr) return out;
    const double cx = sx / sw, cy = sy / sw;
    // var(sum w x / sum w) = sum (x - xc)^2 var(w) / (sum w)^2 to first order.
    double vx = 0.0, vy = 0.0;
    for (int p : comp) {
      const double var = sigma * sigma / count.pixels[p];
      vx += (p % cw - cx) * (p % cw - cx) * var;
      vy += (p / cw - cy) * (p / cw - cy) * var;
    }
    out.x[k] = cx - thirds.residualX[k];
    out.y[k] = cy - thirds.residualY[k];
    out.varX[k] = vx / (sw * sw);
    out.varY[k] = vy / (sw * sw);
  }
  out.measured = true;
  return out;
}

std::pair<double, double> commonShift(const std::vector<SourceShift>& shifts) {
  std::vector<double> dx, dy;
  for (const auto& s : shifts)
    if (s.measured) {
      dx.push_back(s.x[2] - s.x[0]);
      dy.push_back(s.y[2] - s.y[0]);
    }
  if (dx.size() < 3) return {0.0, 0.0};
  return {median(dx), median(dy)};
}

MovingSource judgeMotion(const SourceShift& shift, std::pair<double, double> common,
                         const ThirdStacks& thirds, int x0, int y0, const StaticSourceParams& params,
                         Star& star) {
  MovingSource m;
  m.x = star.x;
  m.y = star.y;
  m.snr = star.snr;
  if (!shift.measured) return m;
  const double dx = shift.x[2] - shift.x[0] - common.first, dy = shift.y[2] - shift.y[0] - common.second;
  const double d = std::hypot(dx, dy);
  const double ux = d > 0 ? dx / d : 1.0, uy = d > 0 ? dy / d : 0.0;
  const double varD = (shift.varX[0] + shift.varX[2]) * ux * ux + (shift.varY[0] + shift.varY[2]) * uy * uy;
  m.shiftPx = d;
  m.shiftSigmaPx = std::sqrt(varD);
  star.motionXPx = dx;
  star.motionYPx = dy;
  star.motionSigmaPx = m.shiftSigmaPx;
  const double dT = thirds.meanTimeS[2] - thirds.meanTimeS[0];
  if (dT <= 0 || d <= std::max(params.minMoverShiftPx, params.moverShiftSigmas * m.shiftSigmaPx)) return m;
  // Linear motion puts the middle third's centroid at the time-weighted point between the outer ones.
  const double f = (thirds.meanTimeS[1] - thirds.meanTimeS[0]) / dT;
  const double ex = shift.x[1] - (shift.x[0] + f * (dx + common.first));
  const double ey = shift.y[1] - (shift.y[0] + f * (dy + common.second));
  const double sigmaMid = std::sqrt(shift.varX[1] + shift.varY[1]);
  m.moving = std::hypot(ex, ey) <= 0.25 * d + params.moverShiftSigmas * sigmaMid;
  m.v = {(dx + common.first) / dT, (dy + common.second) / dT};  // relative to the sky rate
  const double fr = -thirds.meanTimeS[0] / dT;
  m.x = x0 + shift.x[0] + fr * (dx + common.first);
  m.y = y0 + shift.y[0] + fr * (dy + common.second);
  return m;
}

bool vacates(const std::vector<int>& comp, int cw, const ThirdStacks& thirds, double fwhmPx) {
  if (!thirds.valid() || comp.empty()) return false;
  const Image& first = thirds.resid[0];
  const Image& last = thirds.resid[2];
  int p0 = comp.front(), p2 = comp.front();
  for (int p : comp) {
    if (first.pixels[p] > first.pixels[p0]) p0 = p;
    if (last.pixels[p] > last.pixels[p2]) p2 = p;
  }
  const double r = std::max(1.0, fwhmPx);
  if (std::hypot(p0 % cw - p2 % cw, p0 / cw - p2 / cw) < 2.0 * r) return false;
  const int ri = static_cast<int>(std::ceil(r)), ch = first.height;
  auto disc = [&](const Image& im, int centre) {
    double sum = 0.0;
    for (int dy = -ri; dy <= ri; ++dy)
      for (int dx = -ri; dx <= ri; ++dx) {
        const int x = centre % cw + dx, y = centre / cw + dy;
        if (x >= 0 && y >= 0 && x < cw && y < ch && dx * dx + dy * dy <= r * r)
          sum += im.pixels[static_cast<std::size_t>(y) * cw + x];
      }
    return sum;
  };
  const double at0In0 = disc(first, p0), at0In2 = disc(last, p0);
  const double at2In2 = disc(last, p2), at2In0 = disc(first, p2);
  return at0In0 > 0 && at2In2 > 0 && at0In2 < 0.5 * at0In0 && at2In0 < 0.5 * at2In2;
}

}  // namespace st::detect::detail

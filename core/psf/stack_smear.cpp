#include "st/psf/stack_smear.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>

namespace st::psf {

SmearKernel stackSmear(const FrameCube& cube, Velocity rate, double binPx) {
  SmearKernel k;
  const std::vector<double> dt = cube.timeOffsetsS();
  if (dt.empty() || !(binPx > 0.0)) return k;
  std::map<std::pair<long, long>, double> bins;
  double total = 0.0;
  bool spread = false;
  for (std::size_t n = 0; n < dt.size(); ++n) {
    // The same rounding as detect::MovingMask (std::lround).
    const double px = cube.info()[n].offsetXPx + rate.vx * dt[n];
    const double py = cube.info()[n].offsetYPx + rate.vy * dt[n];
    const double rx = px - static_cast<double>(std::lround(px));
    const double ry = py - static_cast<double>(std::lround(py));
    const double tx = rate.vx * cube.info()[n].exposureS, ty = rate.vy * cube.info()[n].exposureS;
    const int steps = std::max(1, static_cast<int>(std::ceil(std::hypot(tx, ty) / (0.5 * binPx))));
    for (int s = 0; s < steps; ++s) {
      const double f = (s + 0.5) / steps - 0.5;
      const double x = rx + tx * f, y = ry + ty * f;
      spread = spread || std::hypot(x, y) >= 0.5 * binPx;
      bins[{std::lround(x / binPx), std::lround(y / binPx)}] += 1.0 / steps;
    }
    total += 1.0;
  }
  if (!spread) return k;
  for (const auto& [key, w] : bins) {
    k.dx.push_back(static_cast<double>(key.first) * binPx);
    k.dy.push_back(static_cast<double>(key.second) * binPx);
    k.weight.push_back(w / total);
  }
  return k;
}

}  // namespace st::psf

#include "st/search/ipsa.hpp"

namespace st::search {

IpsaCell ipsaReference(const FrameCube& cube, const std::vector<double>& dt, int x, int y, Velocity v) {
  IpsaCell cell;
  const int w = cube.width();
  const int h = cube.height();
  for (std::size_t n = 0; n < cube.frameCount(); ++n) {
    const int xs = x + ipsaShift(v.vx, dt[n]);
    const int ys = y + ipsaShift(v.vy, dt[n]);
    if (xs < 0 || ys < 0 || xs >= w || ys >= h) continue;
    cell.sum += cube.frame(n)[static_cast<std::size_t>(ys) * w + xs];
    ++cell.nIn;
  }
  return cell;
}

}  // namespace st::search

#include <algorithm>

#include "st/search/ipsa.hpp"

namespace st::search {

IpsaCell ipsaReference(const FrameCube& cube, const std::vector<double>& dt, int x, int y, Velocity v) {
  IpsaCell cell;
  const int w = cube.width();
  const int h = cube.height();
  for (std::size_t n = 0; n < cube.frameCount(); ++n) {
    const FrameInfo& f = cube.info()[n];
    const int xs = x + ipsaShift(v.vx, dt[n], f.offsetXPx);
    const int ys = y + ipsaShift(v.vy, dt[n], f.offsetYPx);
    if (xs < 0 || ys < 0 || xs >= w || ys >= h) continue;
    cell.sum += cube.frame(n)[static_cast<std::size_t>(ys) * w + xs];
    ++cell.nIn;
  }
  return cell;
}

void countFramesInRow(const int* sx, const int* sy, int frames, int y, int width, int height, int x0, int count,
                      std::vector<int>& diff, int* out) {
  diff.assign(static_cast<std::size_t>(count) + 1, 0);
  for (int k = 0; k < frames; ++k) {
    const int ys = y + sy[k];
    if (ys < 0 || ys >= height) continue;
    // Columns c with 0 <= x0 + c + sx < width.
    const int lo = std::clamp(-sx[k] - x0, 0, count);
    const int hi = std::clamp(width - sx[k] - x0, lo, count);
    ++diff[static_cast<std::size_t>(lo)];
    --diff[static_cast<std::size_t>(hi)];
  }
  int c = 0;
  for (int i = 0; i < count; ++i)
    out[i] = c += diff[static_cast<std::size_t>(i)];
}

}  // namespace st::search

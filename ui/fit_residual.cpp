#include "fit_residual.hpp"

#include <cmath>

#include "st/fit/pixel_psf.hpp"

namespace st::ui {

Image residualAlongTrack(const FrameCube& frames, const fit::FitParams& p, const psf::Moffat& psf, int half) {
  const int side = 2 * half + 1;
  Image out(side, side, 0.0f);
  const fit::PixelPsfTable table(psf, 1.5 * half + 2.0);
  const std::vector<double> times = frames.timeOffsetsS();
  for (std::size_t n = 0; n < frames.frameCount(); ++n) {
    const double px = p.xc + frames.info()[n].offsetXPx + p.v.vx * times[n];
    const double py = p.yc + frames.info()[n].offsetYPx + p.v.vy * times[n];
    const int ox = static_cast<int>(std::lround(px)) - half;
    const int oy = static_cast<int>(std::lround(py)) - half;
    const float* img = frames.frame(n);
    for (int sy = 0; sy < side; ++sy) {
      const int y = oy + sy;
      if (y < 0 || y >= frames.height()) continue;
      for (int sx = 0; sx < side; ++sx) {
        const int x = ox + sx;
        if (x < 0 || x >= frames.width() || frames.isMasked(n, x, y)) continue;
        const double d = img[static_cast<std::size_t>(y) * frames.width() + x];
        if (!std::isfinite(d)) continue;
        out.at(sx, sy) += static_cast<float>(d - (p.alpha * table.value(x - px, y - py) + p.i0));
      }
    }
  }
  return out;
}

}  // namespace st::ui

#include "st/detect/sky_stack.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "st/common/parallel.hpp"
#include "st/stats/sigma_clip.hpp"

namespace st::detect {

SkyStack stackAtSkyRate(const FrameCube& cube, Velocity rate, double subtract, ProgressSink& progress,
                        CancelToken& cancel, std::size_t first, std::size_t last) {
  if (last == 0 || last > cube.frameCount()) last = cube.frameCount();
  const MovingMask geom(cube, rate);
  SkyStack s;
  s.x0 = geom.x0();
  s.y0 = geom.y0();
  const int cw = geom.canvasWidth(), ch = geom.canvasHeight(), w = cube.width(), h = cube.height();
  s.mean = Image(cw, ch);
  s.count = Image(cw, ch);
  s.max = Image(cw, ch, -std::numeric_limits<float>::infinity());
  const auto& mask = cube.mask();
  const std::size_t np = cube.framePixels();
  parallelFor(static_cast<std::size_t>(ch), 8, [&](std::size_t j0, std::size_t j1) {
    std::vector<double> sum(cw);
    for (std::size_t j = j0; j < j1; ++j) {
      cancel.throwIfCancelled();
      std::fill(sum.begin(), sum.end(), 0.0);
      float* cnt = s.count.data() + j * cw;
      float* mx = s.max.data() + j * cw;
      const int refY = s.y0 + static_cast<int>(j);
      for (std::size_t n = first; n < last; ++n) {
        const int y = refY + geom.shiftY(n);
        if (y < 0 || y >= h) continue;
        const int off = geom.shiftX(n) + s.x0;  // frame column x -> canvas column x - off
        const float* row = cube.frame(n) + static_cast<std::size_t>(y) * w;
        const std::uint8_t* mrow =
            mask.empty() ? nullptr : mask.data() + n * np + static_cast<std::size_t>(y) * w;
        for (int x = 0; x < w; ++x) {
          if (mrow && mrow[x]) continue;
          const int i = x - off;
          sum[i] += row[x] - subtract;
          cnt[i] += 1.0f;
          mx[i] = std::max(mx[i], row[x]);
        }
      }
      float* mean = s.mean.data() + j * cw;
      for (int i = 0; i < cw; ++i) {
        mean[i] = cnt[i] > 0 ? static_cast<float>(sum[i] / cnt[i]) : 0.0f;
        if (cnt[i] == 0) mx[i] = 0.0f;
      }
      if (j % 32 == 0) progress.report(static_cast<double>(j) / ch, "stack at sky rate");
    }
  });
  return s;
}

const SkyStack& SkyStackCache::stack(const FrameCube& cube, Velocity rate, double subtract,
                                     ProgressSink& progress, CancelToken& cancel, std::size_t first,
                                     std::size_t last) {
  if (last == 0 || last > cube.frameCount()) last = cube.frameCount();
  const Key key{cube.pixels().data(), rate.vx, rate.vy, subtract, first, last};
  auto it = m_stacks.find(key);
  if (it == m_stacks.end())
    it = m_stacks.emplace(key, stackAtSkyRate(cube, rate, subtract, progress, cancel, first, last)).first;
  else
    progress.report(1.0, "stack at sky rate");
  return it->second;
}

Image meshBackground(const Image& image, const Image& weight, int mesh) {
  const int w = image.width, h = image.height;
  mesh = std::max(4, mesh);
  const int nx = std::max(1, (w + mesh - 1) / mesh), ny = std::max(1, (h + mesh - 1) / mesh);
  std::vector<double> cell(static_cast<std::size_t>(nx) * ny, std::numeric_limits<double>::quiet_NaN());
  std::vector<float> v;
  for (int cy = 0; cy < ny; ++cy)
    for (int cx = 0; cx < nx; ++cx) {
      v.clear();
      for (int y = cy * mesh; y < std::min(h, (cy + 1) * mesh); ++y)
        for (int x = cx * mesh; x < std::min(w, (cx + 1) * mesh); ++x)
          if (weight.at(x, y) > 0) v.push_back(image.at(x, y));
      if (v.size() >= 8)
        cell[static_cast<std::size_t>(cy) * nx + cx] = stats::sigmaClip(v.data(), v.size(), 3.0).mean;
    }
  // Empty cells take the mean of the filled ones.
  double fill = 0.0;
  int nFill = 0;
  for (double c : cell)
    if (!std::isnan(c)) fill += c, ++nFill;
  fill = nFill ? fill / nFill : 0.0;
  for (double& c : cell)
    if (std::isnan(c)) c = fill;
  Image out(w, h);
  for (int y = 0; y < h; ++y) {
    const double fy = std::clamp((y + 0.5) / mesh - 0.5, 0.0, ny - 1.0);
    const int iy = std::min(static_cast<int>(fy), ny - 1), iy1 = std::min(iy + 1, ny - 1);
    const double ty = fy - iy;
    for (int x = 0; x < w; ++x) {
      const double fx = std::clamp((x + 0.5) / mesh - 0.5, 0.0, nx - 1.0);
      const int ix = std::min(static_cast<int>(fx), nx - 1), ix1 = std::min(ix + 1, nx - 1);
      const double tx = fx - ix;
      auto c = [&](int a, int b) { return cell[static_cast<std::size_t>(b) * nx + a]; };
      out.at(x, y) = static_cast<float>((1 - ty) * ((1 - tx) * c(ix, iy) + tx * c(ix1, iy)) +
                                        ty * ((1 - tx) * c(ix, iy1) + tx * c(ix1, iy1)));
    }
  }
  return out;
}

}  // namespace st::detect

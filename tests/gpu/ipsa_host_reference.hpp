#pragma once
// A plain host reference of the exact IPSA search for the GPU tests (ARCHITECTURE.md "IPSA", "SNR"):
// a naive loop over velocities, pixels and frames, accumulated in double. Map: highest SNR per velocity
// over cells with N_in >= minFrames (ties: lowest y, then x); cells: SNR strictly above threshold.
#include <cmath>
#include <vector>

#include "st/search/types.hpp"

namespace st::test {

struct RefCell {
  int x, y, ivx, ivy, nIn;
  double sum, snr;
};

struct RefSearch {
  std::vector<double> mapSnr;   ///< [nvy][nvx], 0 where no valid cell
  std::vector<int> argX, argY;  ///< -1 where no valid cell
  std::vector<RefCell> cells;   ///< above threshold, in scan order
  std::vector<double> snr;      ///< [nvy][nvx][H][W] every cell's SNR (NaN where ignored)
};

/// round(o + v dt): o is the frame's registration offset (FrameInfo::offsetXPx/offsetYPx, usually 0).
inline int refShift(double v, double dt, double o = 0.0) {
  return static_cast<int>(std::lround(o + v * dt));
}

inline RefSearch refSearch(const search::FilteredCube& cube, const search::VelocityGrid& grid,
                           double threshold, int minFrames) {
  const FrameCube& f = cube.frames;
  const int w = f.width();
  const int h = f.height();
  const std::vector<double> dt = f.timeOffsetsS();
  const int n = static_cast<int>(dt.size());
  RefSearch r;
  const std::size_t nv = grid.count();
  r.mapSnr.assign(nv, 0.0);
  r.argX.assign(nv, -1);
  r.argY.assign(nv, -1);
  r.snr.assign(nv * w * h, std::nan(""));
  std::vector<int> sx(n), sy(n);
  for (int iy = 0; iy < grid.nvy; ++iy) {
    for (int ix = 0; ix < grid.nvx; ++ix) {
      const Velocity v = grid.at(ix, iy);
      for (int k = 0; k < n; ++k) {
        sx[k] = refShift(v.vx, dt[k], f.info()[k].offsetXPx);
        sy[k] = refShift(v.vy, dt[k], f.info()[k].offsetYPx);
      }
      const std::size_t iv = static_cast<std::size_t>(iy) * grid.nvx + ix;
      double best = -1e300;
      for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
          double sum = 0.0;
          int nIn = 0;
          for (int k = 0; k < n; ++k) {
            const int xx = x + sx[k];
            const int yy = y + sy[k];
            if (xx < 0 || yy < 0 || xx >= w || yy >= h) continue;
            sum += f.frame(k)[static_cast<std::size_t>(yy) * w + xx];
            ++nIn;
          }
          if (nIn < minFrames || nIn == 0) continue;
          const double snr = sum / (cube.sigmaF * std::sqrt(static_cast<double>(nIn)));
          r.snr[(iv * h + y) * w + x] = snr;
          if (snr > best) {
            best = snr;
            r.mapSnr[iv] = snr;
            r.argX[iv] = x;
            r.argY[iv] = y;
          }
          if (snr > threshold) r.cells.push_back(RefCell{x, y, ix, iy, nIn, sum, snr});
        }
      }
    }
  }
  return r;
}

/// Host stack of the cube at v: IPSA (integer shifts) or CSA (bilinear at v dt; a sample counts when its
/// position lies inside the frame).
inline Image refStack(const FrameCube& f, Velocity v, bool csa) {
  const int w = f.width();
  const int h = f.height();
  const std::vector<double> dt = f.timeOffsetsS();
  std::vector<double> acc(static_cast<std::size_t>(w) * h, 0.0);
  for (std::size_t k = 0; k < dt.size(); ++k) {
    const float* fr = f.frame(k);
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        double s = 0.0;
        if (!csa) {
          const int xx = x + refShift(v.vx, dt[k], f.info()[k].offsetXPx);
          const int yy = y + refShift(v.vy, dt[k], f.info()[k].offsetYPx);
          if (xx < 0 || yy < 0 || xx >= w || yy >= h) continue;
          s = fr[static_cast<std::size_t>(yy) * w + xx];
        } else {
          const double fx = x + static_cast<double>(static_cast<float>(v.vx * dt[k]));
          const double fy = y + static_cast<double>(static_cast<float>(v.vy * dt[k]));
          if (!(fx >= 0 && fy >= 0 && fx <= w - 1 && fy <= h - 1)) continue;
          const int xa = std::min(static_cast<int>(std::floor(fx)), w - 1);
          const int ya = std::min(static_cast<int>(std::floor(fy)), h - 1);
          const int xb = std::min(xa + 1, w - 1);
          const int yb = std::min(ya + 1, h - 1);
          const double ax = fx - xa;
          const double ay = fy - ya;
          auto px = [&](int xi, int yi) {
            return static_cast<double>(fr[static_cast<std::size_t>(yi) * w + xi]);
          };
          s = (1 - ay) * ((1 - ax) * px(xa, ya) + ax * px(xb, ya)) +
              ay * ((1 - ax) * px(xa, yb) + ax * px(xb, yb));
        }
        acc[static_cast<std::size_t>(y) * w + x] += s;
      }
    }
  }
  Image out(w, h);
  for (std::size_t i = 0; i < acc.size(); ++i)
    out.pixels[i] = static_cast<float>(acc[i]);
  return out;
}

}  // namespace st::test

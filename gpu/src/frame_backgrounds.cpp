// The host side of SEP's background on the device (frame_backgrounds.hpp): per frame, SEP's filterback and
// makebackspline on the meshes the device measured; per row and column, the constants of its spline
// evaluation. Written step by step as SEP 1.2's background.c computes them (float where SEP is float, its
// double literals promoting where it promotes; this file is compiled for baseline x86-64, without fused
// multiply-adds), so the spline nodes and the global level and rms are SEP's for the same mesh values.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <vector>

#include "cuda_check.hpp"
#include "frame_backgrounds.hpp"
#include "st/common/parallel.hpp"

namespace st::gpu {
namespace {

constexpr float kBigF = static_cast<float>(kSepBig);

/// SEP's fqmedian (util.c): sorts `ra`, the middle value or the mean of the two middle ones.
float fqmedian(float* ra, int n) {
  std::sort(ra, ra + n, [](float a, float b) { return static_cast<double>(a) < static_cast<double>(b); });
  if (n < 2) return *ra;
  return n & 1 ? ra[n / 2] : static_cast<float>((ra[n / 2 - 1] + ra[n / 2]) / 2.0);
}

/// SEP's filterback with fthresh = 0: bad meshes filled from their nearest valid ones, the fw x fh median
/// filter of back and sigma, the global level and rms.
void filterback(int nx, int ny, int fw, int fh, float* back, float* sigma, float& global, float& globalrms) {
  const int np = nx * ny;
  const int npx = fw / 2;
  const int npy = (fh / 2) * nx;
  std::vector<float> bmask(static_cast<std::size_t>((2 * npx + 1) * (2 * (fh / 2) + 1)));
  std::vector<float> smask(bmask.size());
  std::vector<float> back2(static_cast<std::size_t>(np)), sigma2(static_cast<std::size_t>(np));
  float val = 0.0f, sval = 0.0f;
  for (int i = 0, py = 0; py < ny; ++py)
    for (int px = 0; px < nx; ++px, ++i)
      if ((back2[i] = back[i]) <= -kBigF) {
        float d2min = kBigF;
        int nmin = 0;
        for (int j = 0, y = 0; y < ny; ++y)
          for (int x = 0; x < nx; ++x, ++j)
            if (back[j] > -kBigF) {
              const float d2 = static_cast<float>(x - px) * (x - px) + (y - py) * (y - py);
              if (d2 < d2min) {
                val = back[j];
                sval = sigma[j];
                nmin = 1;
                d2min = d2;
              } else if (d2 == d2min) {
                val += back[j];
                sval += sigma[j];
                ++nmin;
              }
            }
        back2[i] = nmin ? val / nmin : 0.0f;
        sigma[i] = nmin ? sval / nmin : 1.0f;
      }
  std::copy(back2.begin(), back2.end(), back);
  for (int py = 0; py < np; py += nx) {
    int npy2 = np - py - nx;
    if (npy2 > npy) npy2 = npy;
    if (npy2 > py) npy2 = py;
    for (int px = 0; px < nx; ++px) {
      int npx2 = nx - px - 1;
      if (npx2 > npx) npx2 = npx;
      if (npx2 > px) npx2 = px;
      int i = 0;
      for (int dpy = -npy2; dpy <= npy2; dpy += nx) {
        const int y = py + dpy;
        for (int dpx = -npx2; dpx <= npx2; ++dpx) {
          const int x = px + dpx;
          bmask[i] = back[x + y];
          smask[i++] = sigma[x + y];
        }
      }
      const float med = fqmedian(bmask.data(), i);
      if (std::fabs(med - back[px + py]) >= 0.0) {
        back2[px + py] = med;
        sigma2[px + py] = fqmedian(smask.data(), i);
      } else {
        back2[px + py] = back[px + py];
        sigma2[px + py] = sigma[px + py];
      }
    }
  }
  std::copy(back2.begin(), back2.end(), back);
  global = fqmedian(back2.data(), np);
  std::copy(sigma2.begin(), sigma2.end(), sigma);
  globalrms = fqmedian(sigma2.data(), np);
  if (globalrms <= 0.0f) {
    // sigma2 is sorted now: the median of its positive tail.
    int i = np;
    const float* sigmat = sigma2.data() + np;
    while (i-- && *(--sigmat) > 0.0f) {
    }
    globalrms = (i >= 0 && i < np - 1) ? fqmedian(sigma2.data() + i + 1, np - 1 - i) : 1.0f;
  }
}

/// SEP's makebackspline: the second derivatives along y of `map` ([ny][nx]) into `dmap`.
void makebackspline(int nx, int ny, const float* map, float* dmap) {
  std::vector<float> u(static_cast<std::size_t>(std::max(1, ny - 1)));
  for (int x = 0; x < nx; ++x) {
    if (ny > 1) {
      dmap[x] = u[0] = 0.0f;
      for (int y = 1; y < ny - 1; ++y) {
        const float* m = map + static_cast<std::size_t>(y) * nx + x;
        float temp = -1 / (dmap[static_cast<std::size_t>(y - 1) * nx + x] + 4);
        dmap[static_cast<std::size_t>(y) * nx + x] = temp;
        temp *= u[y - 1] - 6 * (*(m + nx) + *(m - nx) - 2 * *m);
        u[y] = temp;
      }
      dmap[static_cast<std::size_t>(ny - 1) * nx + x] = 0.0f;
      for (int y = ny - 1; y >= 2; --y) {
        const float temp = dmap[static_cast<std::size_t>(y) * nx + x];
        float& d = dmap[static_cast<std::size_t>(y - 1) * nx + x];
        d = static_cast<float>((d * temp + u[y - 1]) / 6.0);
      }
    } else {
      dmap[x] = 0.0f;
    }
  }
}

/// bkg_line_flt_internal's y constants per row.
std::vector<SepRow> rowTable(int height, int bh, int ny) {
  std::vector<SepRow> rows(static_cast<std::size_t>(height));
  for (int y = 0; y < height; ++y) {
    float dy = static_cast<float>(static_cast<float>(y) / static_cast<float>(bh) - 0.5);
    int yl = static_cast<int>(dy);
    dy -= static_cast<float>(yl);
    if (yl < 0) {
      yl = 0;
      dy = static_cast<float>(dy - 1.0);
    } else if (yl >= ny - 1) {
      yl = ny < 2 ? 0 : ny - 2;
      dy = static_cast<float>(dy + 1.0);
    }
    const float cdy = 1 - dy;
    rows[y] = SepRow{yl, dy, cdy, dy * dy * dy - dy, cdy * cdy * cdy - cdy};
  }
  return rows;
}

/// bkg_line_flt_internal's x steps per column (its dx accumulates in float along the row).
std::vector<SepColumn> columnTable(int width, int bw, int nbx) {
  std::vector<SepColumn> cols(static_cast<std::size_t>(width));
  const int nbxm1 = nbx - 1;
  const int nx = bw;
  const float xstep = static_cast<float>(1.0 / nx);
  const int changepoint = nx / 2;
  float dx = (xstep - 1) / 2;
  const float dx0 = ((nx + 1) % 2) * xstep / 2;
  int blo = 0;
  int col = 0;
  for (int x = 0, i = 0, j = width; j--; ++i, dx += xstep) {
    if (i == changepoint && x > 0 && x < nbxm1) {
      ++blo;
      dx = dx0;
    }
    const float cdx = 1 - dx;
    cols[col++] = SepColumn{blo, dx, cdx, cdx * cdx - 1, dx * dx - 1};
    if (i == nx) {
      ++x;
      i = 0;
    }
  }
  return cols;
}

}  // namespace

SepFrameBackgrounds removeFrameBackgroundsOnDevice(float* pix, const std::uint8_t* mask, int width,
                                                   int height, int nf, int meshPx, int filterCells,
                                                   cudaStream_t stream) {
  using clock = std::chrono::steady_clock;
  SepFrameBackgrounds out;
  out.level.assign(static_cast<std::size_t>(nf), std::nan(""));
  out.rms.assign(static_cast<std::size_t>(nf), std::nan(""));
  if (nf <= 0 || width <= 0 || height <= 0) return out;
  const int mesh = std::max(8, meshPx), filter = std::max(1, filterCells);
  const int bw = std::min(mesh, width), bh = std::min(mesh, height);
  const int nx = (width - 1) / bw + 1, ny = (height - 1) / bh + 1;
  const std::size_t nb = static_cast<std::size_t>(nx) * ny;
  auto t0 = clock::now();
  DeviceBuffer<float> back(static_cast<std::size_t>(nf) * nb), sigma(static_cast<std::size_t>(nf) * nb);
  const double pi = 3.1415926535898;  // SEP's PI
  SepMeshLaunch m{pix,        mask,       width, height, nf, bw, bh, nx, ny, std::sqrt(2 / pi) * 5 / 4,
                  back.get(), sigma.get()};
  launchSepMeshes(m, stream);
  std::vector<float> b(back.size()), s(sigma.size()), db(back.size());
  ST_CUDA_CHECK(
      cudaMemcpyAsync(b.data(), back.get(), b.size() * sizeof(float), cudaMemcpyDeviceToHost, stream));
  ST_CUDA_CHECK(
      cudaMemcpyAsync(s.data(), sigma.get(), s.size() * sizeof(float), cudaMemcpyDeviceToHost, stream));
  ST_CUDA_CHECK(cudaStreamSynchronize(stream));
  auto t1 = clock::now();
  out.meshSeconds = std::chrono::duration<double>(t1 - t0).count();
  parallelFor(static_cast<std::size_t>(nf), 16, [&](std::size_t lo, std::size_t hi) {
    for (std::size_t n = lo; n < hi; ++n) {
      float global = 0.0f, globalrms = 0.0f;
      filterback(nx, ny, filter, filter, b.data() + n * nb, s.data() + n * nb, global, globalrms);
      makebackspline(nx, ny, b.data() + n * nb, db.data() + n * nb);
      out.level[n] = global;
      out.rms[n] = globalrms;
    }
  });
  std::vector<double> levels;
  for (const double l : out.level)
    if (std::isfinite(l)) levels.push_back(l);
  if (!levels.empty()) {
    const auto mid = levels.begin() + static_cast<std::ptrdiff_t>(levels.size() / 2);
    std::nth_element(levels.begin(), mid, levels.end());
    out.restored = *mid;
  }
  const std::vector<SepRow> rows = rowTable(height, bh, ny);
  const std::vector<SepColumn> cols = columnTable(width, bw, nx);
  auto t2 = clock::now();
  out.hostSeconds = std::chrono::duration<double>(t2 - t1).count();
  DeviceBuffer<float> dback(db.size());
  ST_CUDA_CHECK(
      cudaMemcpyAsync(back.get(), b.data(), b.size() * sizeof(float), cudaMemcpyHostToDevice, stream));
  ST_CUDA_CHECK(
      cudaMemcpyAsync(dback.get(), db.data(), db.size() * sizeof(float), cudaMemcpyHostToDevice, stream));
  DeviceBuffer<SepRow> rowsD = toDevice(rows);
  DeviceBuffer<SepColumn> colsD = toDevice(cols);
  SepSubtractLaunch sub{pix,
                        width,
                        height,
                        nf,
                        nx,
                        ny,
                        back.get(),
                        dback.get(),
                        rowsD.get(),
                        colsD.get(),
                        static_cast<float>(out.restored)};
  launchSepSubtract(sub, stream);
  ST_CUDA_CHECK(cudaStreamSynchronize(stream));
  out.subtractSeconds = std::chrono::duration<double>(clock::now() - t2).count();
  return out;
}

}  // namespace st::gpu

#include "st/stats/sep_background.hpp"

#include <algorithm>
#include <cmath>

namespace st::stats::sep {
namespace {

constexpr float kBigF = static_cast<float>(kBig);

struct MeshSums {
  double s = 0.0, ss = 0.0;
  int n = 0;
};

// backstat's two passes over up to four meshes of width mw side by side (their first columns in x0[]),
// each mesh's samples in SEP's order (row by row); the meshes interleaved so that their sums' dependency
// chains overlap. `cut` false: every unmasked sample above -BIG; true: the unmasked samples within
// [lcut, hcut].
template <bool kCut>
void meshSums(const float* frame, const std::uint8_t* mask, int width, int y0, int mh, int mw, const int* x0,
              int count, const float* lcut, const float* hcut, MeshSums* out) {
  double s[4] = {0.0, 0.0, 0.0, 0.0}, ss[4] = {0.0, 0.0, 0.0, 0.0};
  int n[4] = {0, 0, 0, 0};
  for (int y = y0; y < y0 + mh; ++y) {
    const std::size_t row = static_cast<std::size_t>(y) * width;
    for (int x = 0; x < mw; ++x)
      for (int q = 0; q < count; ++q) {
        const std::size_t i = row + x0[q] + x;
        const double pix = frame[i];
        bool in = !mask || mask[i] == 0;
        if constexpr (kCut)
          in = in && pix <= hcut[q] && pix >= lcut[q];
        else
          in = in && pix > -kBig;
        const double d = in ? pix : 0.0;  // + 0.0 leaves a sum that started at +0.0 as it was
        s[q] += d;
        ss[q] += d * d;
        n[q] += in;
      }
  }
  for (int q = 0; q < count; ++q)
    out[q] = {s[q], ss[q], n[q]};
}

// backstat's result for one mesh.
struct MeshStat {
  bool bad = true;
  float mean = 0.0f, sigma = 0.0f, qscale = 1.0f, qzero = 0.0f;
  int nlevels = 1;
};

// backguess of one mesh from its histogram `hist` (nlevels bins; read through `at`, 0 beyond them, as the
// device reads its zeroed 4096 bins), with the clipped sums from prefix sums (integers: exact).
struct Histogram {
  std::vector<int> hist;
  std::vector<long long> p0, p1, p2;  // prefix sums of h, h k, h k^2: p[k] = sum over bins < k
  int nlevels = 0;
  int at(int k) const { return k >= 0 && k < nlevels ? hist[static_cast<std::size_t>(k)] : 0; }
};

void backguess(const MeshStat& m, const Histogram& h, float& back, float& sigma) {
  const int nlevelsm1 = m.nlevels - 1;
  int lo = 0, hi = nlevelsm1;
  double sig = 10.0 * nlevelsm1, sig1 = 1.0;
  double mea = m.mean, med = m.mean;
  for (int n = 100; n-- != 0 && sig >= 0.1 && std::fabs(sig / sig1 - 1.0) > 1e-4;) {
    sig1 = sig;
    long long sh = 0, shi = 0, shii = 0;
    int hilow = lo, hihigh = hi;
    long long lowsum = 0, highsum = 0;
    const int count = hi - lo + 1;
    if (count > 0) {
      // lo >= 0 and hi <= nlevels - 1 here (the cuts below keep them so).
      sh = h.p0[hi + 1] - h.p0[lo];
      shi = h.p1[hi + 1] - h.p1[lo];
      shii = h.p2[hi + 1] - h.p2[lo];
      // SEP's walk: lowsum from bin lo up, highsum from bin hi down, the smaller side advancing (high on a
      // tie) for count steps; it stops with the low side past bin lo + a - 1, a the first index with
      // P_a + P_(a+1) >= T (P the prefix counts from lo, T their total), and highsum = T - P_a.
      const long long base = h.p0[lo], total = sh;
      int l = 0, r = count - 1;  // r = count - 1 satisfies the condition (P_count = T)
      while (l < r) {
        const int mid = (l + r) / 2;
        if ((h.p0[lo + mid] - base) + (h.p0[lo + mid + 1] - base) >= total)
          r = mid;
        else
          l = mid + 1;
      }
      hilow = lo + l;
      hihigh = lo + l - 1;
      lowsum = h.p0[lo + l] - base;
      highsum = total - lowsum;
    }
    if (hihigh >= 0) {
      const int hl = h.at(hilow), hh = h.at(hihigh);
      med =
          (static_cast<double>(hihigh) + 0.5) + (static_cast<double>(highsum) - static_cast<double>(lowsum)) /
                                                    (2.0 * static_cast<double>(hl > hh ? hl : hh));
    } else {
      med = 0.0;
    }
    mea = static_cast<double>(shi);
    sig = static_cast<double>(shii);
    if (sh) {
      const double sum = static_cast<double>(sh);
      mea /= sum;
      sig = sig / sum - mea * mea;
    }
    sig = sig > 0.0 ? std::sqrt(sig) : 0.0;
    double ftemp = med - 3.0 * sig;
    lo = ftemp > 0.0 ? static_cast<int>(ftemp + 0.5) : 0;
    ftemp = med + 3.0 * sig;
    hi = ftemp < nlevelsm1 ? static_cast<int>(ftemp > 0.0 ? ftemp + 0.5 : ftemp - 0.5) : nlevelsm1;
    lo = std::min(lo, m.nlevels);  // past every bin: no sums (SEP's loop would not run either)
  }
  const double qzero = m.qzero, qscale = m.qscale;
  double mode;
  if (std::fabs(sig) > 0.0)
    mode =
        std::fabs((mea - med) / sig) < 0.3 ? qzero + (2.5 * med - 1.5 * mea) * qscale : qzero + med * qscale;
  else
    mode = qzero + mea * qscale;
  back = static_cast<float>(mode);
  sigma = static_cast<float>(sig * qscale);
}

}  // namespace

double histogramStep() {
  return std::sqrt(2 / kPi) * 5 / 4;
}

MeshGrid meshGrid(int width, int height, int meshPx) {
  MeshGrid g;
  g.width = width;
  g.height = height;
  const int mesh = std::max(8, meshPx);
  g.bw = std::min(mesh, width);
  g.bh = std::min(mesh, height);
  g.nx = std::max(1, (width - 1) / std::max(1, g.bw) + 1);
  g.ny = std::max(1, (height - 1) / std::max(1, g.bh) + 1);
  return g;
}

void meshStatistics(const float* frame, const std::uint8_t* mask, const MeshGrid& g, float* back,
                    float* sigma) {
  const double step = histogramStep();
  thread_local Histogram h;
  h.hist.resize(kMaxLevels);
  h.p0.resize(kMaxLevels + 1);
  h.p1.resize(kMaxLevels + 1);
  h.p2.resize(kMaxLevels + 1);
  std::vector<MeshStat> stats(static_cast<std::size_t>(g.nx));
  for (int j = 0; j < g.ny; ++j) {
    const int y0 = j * g.bh;
    const int mh = (j == g.ny - 1 && g.height % g.bh) ? g.height % g.bh : g.bh;
    // backstat: the full-width meshes four at a time, the narrower last one alone.
    for (int i0 = 0; i0 < g.nx;) {
      const int mw = (i0 == g.nx - 1 && g.width % g.bw) ? g.width % g.bw : g.bw;
      int count = 1;
      while (count < 4 && i0 + count < g.nx &&
             !(i0 + count == g.nx - 1 && g.width % g.bw))  // the narrower last mesh goes alone
        ++count;
      int x0[4];
      for (int q = 0; q < count; ++q)
        x0[q] = (i0 + q) * g.bw;
      MeshSums first[4], second[4];
      meshSums<false>(frame, mask, g.width, y0, mh, mw, x0, count, nullptr, nullptr, first);
      float lcut[4] = {0, 0, 0, 0}, hcut[4] = {0, 0, 0, 0};
      bool anyGood = false;
      for (int q = 0; q < count; ++q) {
        MeshStat& st = stats[static_cast<std::size_t>(i0 + q)];
        st = MeshStat{};
        st.bad = static_cast<float>(first[q].n) < static_cast<float>(static_cast<double>(mw * mh) * 0.5);
        if (st.bad) {
          lcut[q] = 1.0f;  // an empty range: no sample passes
          hcut[q] = 0.0f;
          continue;
        }
        anyGood = true;
        const double n = first[q].n;
        const double mean = first[q].s / n;
        const double sig = first[q].ss / n - mean * mean;
        const double sd = sig > 0.0 ? std::sqrt(sig) : 0.0;
        lcut[q] = static_cast<float>(mean - 2.0 * sd);
        hcut[q] = static_cast<float>(mean + 2.0 * sd);
      }
      if (anyGood) meshSums<true>(frame, mask, g.width, y0, mh, mw, x0, count, lcut, hcut, second);
      for (int q = 0; q < count; ++q) {
        MeshStat& st = stats[static_cast<std::size_t>(i0 + q)];
        if (st.bad) continue;
        const double n = second[q].n;
        const double mean = second[q].s / n;
        const double sig = second[q].ss / n - mean * mean;
        const double sd = sig > 0.0 ? std::sqrt(sig) : 0.0;
        st.mean = static_cast<float>(mean);
        st.sigma = static_cast<float>(sd);
        st.nlevels = static_cast<int>(step * second[q].n + 1);
        if (st.nlevels > kMaxLevels) st.nlevels = kMaxLevels;
        st.qscale = sd > 0.0 ? static_cast<float>(10.0 * sd / st.nlevels) : 1.0f;
        st.qzero = static_cast<float>(mean - 5.0 * sd);
      }
      i0 += count;
    }
    // backhisto and backguess, mesh by mesh.
    for (int i = 0; i < g.nx; ++i) {
      const MeshStat& st = stats[static_cast<std::size_t>(i)];
      const std::size_t k = static_cast<std::size_t>(j) * g.nx + i;
      if (st.bad) {
        back[k] = -kBigF;
        sigma[k] = -kBigF;
        continue;
      }
      const int mw = (i == g.nx - 1 && g.width % g.bw) ? g.width % g.bw : g.bw;
      const int x0 = i * g.bw;
      const int nlevels = st.nlevels;
      const float qscale = st.qscale;
      // cste = 0.499999 - qzero / qscale: the quotient in float, the difference in double, kept as float.
      const float cste = static_cast<float>(0.499999 - static_cast<double>(st.qzero / qscale));
      const float top = static_cast<float>(nlevels);
      std::fill(h.hist.begin(), h.hist.begin() + nlevels, 0);
      for (int y = y0; y < y0 + mh; ++y) {
        const std::size_t row = static_cast<std::size_t>(y) * g.width + x0;
        const float* f = frame + row;
        const std::uint8_t* mk = mask ? mask + row : nullptr;
        for (int x = 0; x < mw; ++x) {
          const float b = f[x] / qscale + cste;
          // (int)b in [0, nlevels) exactly when -1 < b < nlevels (truncation toward 0); NaN fails both.
          if (b > -1.0f && b < top && (!mk || mk[x] == 0))
            ++h.hist[static_cast<std::size_t>(static_cast<int>(b))];
        }
      }
      h.nlevels = nlevels;
      h.p0[0] = h.p1[0] = h.p2[0] = 0;
      for (int b = 0; b < nlevels; ++b) {
        const long long c = h.hist[static_cast<std::size_t>(b)];
        h.p0[b + 1] = h.p0[b] + c;
        h.p1[b + 1] = h.p1[b] + c * b;
        h.p2[b + 1] = h.p2[b] + c * b * b;
      }
      backguess(st, h, back[k], sigma[k]);
    }
  }
}

float fqmedian(float* ra, int n) {
  std::sort(ra, ra + n, [](float a, float b) { return static_cast<double>(a) < static_cast<double>(b); });
  if (n < 2) return *ra;
  return n & 1 ? ra[n / 2] : static_cast<float>((ra[n / 2 - 1] + ra[n / 2]) / 2.0);
}

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

std::vector<SplineRow> rowTable(int height, int bh, int ny) {
  std::vector<SplineRow> rows(static_cast<std::size_t>(height));
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
    rows[static_cast<std::size_t>(y)] = SplineRow{yl, dy, cdy, dy * dy * dy - dy, cdy * cdy * cdy - cdy};
  }
  return rows;
}

std::vector<SplineColumn> columnTable(int width, int bw, int nx) {
  std::vector<SplineColumn> cols(static_cast<std::size_t>(width));
  const int nxm1 = nx - 1;
  const float xstep = static_cast<float>(1.0 / bw);
  const int changepoint = bw / 2;
  float dx = (xstep - 1) / 2;
  const float dx0 = ((bw + 1) % 2) * xstep / 2;
  int blo = 0;
  int col = 0;
  for (int x = 0, i = 0, j = width; j--; ++i, dx += xstep) {
    if (i == changepoint && x > 0 && x < nxm1) {
      ++blo;
      dx = dx0;
    }
    const float cdx = 1 - dx;
    cols[static_cast<std::size_t>(col++)] = SplineColumn{blo, dx, cdx, cdx * cdx - 1, dx * dx - 1};
    if (i == bw) {
      ++x;
      i = 0;
    }
  }
  return cols;
}

FrameModel model(const float* frame, const std::uint8_t* mask, const MeshGrid& g, int filterCells) {
  FrameModel m;
  const std::size_t nb = static_cast<std::size_t>(g.meshes());
  m.back.resize(nb);
  m.sigma.resize(nb);
  m.dback.resize(nb);
  meshStatistics(frame, mask, g, m.back.data(), m.sigma.data());
  const int f = std::max(1, filterCells);
  filterback(g.nx, g.ny, f, f, m.back.data(), m.sigma.data(), m.global, m.globalrms);
  makebackspline(g.nx, g.ny, m.back.data(), m.dback.data());
  return m;
}

void subtract(float* frame, const MeshGrid& g, const FrameModel& m, const std::vector<SplineRow>& rows,
              const std::vector<SplineColumn>& cols, float restored) {
  const int nx = g.nx;
  std::vector<float> nodeBuf(static_cast<std::size_t>(nx)), dnodeBuf(static_cast<std::size_t>(nx)),
      u(static_cast<std::size_t>(nx));
  for (int y = 0; y < g.height; ++y) {
    const float* node = m.back.data();
    const float* dnode = m.dback.data();
    if (g.ny > 1) {
      const SplineRow& r = rows[static_cast<std::size_t>(y)];
      const float* blo = m.back.data() + static_cast<std::size_t>(r.yl) * nx;
      const float* dblo = m.dback.data() + static_cast<std::size_t>(r.yl) * nx;
      for (int k = 0; k < nx; ++k)
        nodeBuf[k] = r.cdy * blo[k] + r.dy * blo[k + nx] + r.cdy3 * dblo[k] + r.dy3 * dblo[k + nx];
      if (nx > 1) {
        // The x second derivatives ("natural" spline), in SEP's order.
        dnodeBuf[0] = u[0] = 0.0f;
        for (int k = 1; k < nx - 1; ++k) {
          float temp = -1.0f / (dnodeBuf[k - 1] + 4.0f);
          dnodeBuf[k] = temp;
          temp *= u[k - 1] - 6.0f * (nodeBuf[k + 1] + nodeBuf[k - 1] - 2.0f * nodeBuf[k]);
          u[k] = temp;
        }
        dnodeBuf[nx - 1] = 0.0f;
        for (int k = nx - 1; k >= 2; --k)
          dnodeBuf[k - 1] = static_cast<float>((dnodeBuf[k - 1] * dnodeBuf[k] + u[k - 1]) / 6.0);
      }
      node = nodeBuf.data();
      dnode = dnodeBuf.data();
    }
    float* row = frame + static_cast<std::size_t>(y) * g.width;
    if (nx > 1) {
      for (int x = 0; x < g.width; ++x) {
        const SplineColumn& c = cols[static_cast<std::size_t>(x)];
        const int k = c.node;
        const float line = c.cdx * (node[k] + c.a * dnode[k]) + c.dx * (node[k + 1] + c.b * dnode[k + 1]);
        row[x] = (row[x] - line) + restored;
      }
    } else {
      const float line = node[0];
      for (int x = 0; x < g.width; ++x)
        row[x] = (row[x] - line) + restored;
    }
  }
}

}  // namespace st::stats::sep

#include "st/stack/csa.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <complex>
#include <cstring>
#include <string>

#include "st/common/error.hpp"
#include "st/common/fftw_plans.hpp"
#include "st/common/parallel.hpp"

namespace st::stack {
namespace {

using fftw::CplxBuf;
using fftw::PlanPair;
using fftw::RealBuf;

RealBuf allocReal(std::size_t n) { return fftw::allocReal(n, "CSA stack"); }
CplxBuf allocCplx(std::size_t n) { return fftw::allocCplx(n, "CSA stack"); }

/// exp(2 pi i k Delta / n) for k = 0..count-1 with signed frequencies (k > n/2 -> k - n). At the Nyquist
/// frequency of an even n the factor is real, cos(pi Delta), so the shifted image stays real.
void phaseRamp(int n, int count, double delta, std::vector<std::complex<float>>& out) {
  out.resize(std::size_t(count));
  for (int k = 0; k < count; ++k) {
    if (2 * k == n) {
      out[std::size_t(k)] = {static_cast<float>(std::cos(M_PI * delta)), 0.0f};
      continue;
    }
    const int f = k <= n / 2 ? k : k - n;
    const double a = 2.0 * M_PI * f * delta / n;
    out[std::size_t(k)] = {static_cast<float>(std::cos(a)), static_cast<float>(std::sin(a))};
  }
}

/// acc += spec * py[ky] * px[kx] over the half spectrum (ny rows of hx values).
void accumulateShifted(const fftwf_complex* spec, fftwf_complex* acc, int hx, int ny,
                       const std::vector<std::complex<float>>& px, const std::vector<std::complex<float>>& py,
                       std::vector<std::complex<float>>& row) {
  row.resize(std::size_t(hx));
  for (int ky = 0; ky < ny; ++ky) {
    const std::complex<float> fy = py[std::size_t(ky)];
    for (int kx = 0; kx < hx; ++kx)
      row[std::size_t(kx)] = fy * px[std::size_t(kx)];
    const float* __restrict s = spec[std::size_t(ky) * hx];
    float* __restrict a = acc[std::size_t(ky) * hx];
    const float* __restrict f = reinterpret_cast<const float*>(row.data());
    for (int kx = 0; kx < hx; ++kx) {
      const float sr = s[2 * kx], si = s[2 * kx + 1], fr = f[2 * kx], fi = f[2 * kx + 1];
      a[2 * kx] += sr * fr - si * fi;
      a[2 * kx + 1] += sr * fi + si * fr;
    }
  }
}

/// N_in by the IPSA rule (rounded shifts), as in ipsaRows.
void countFrames(const std::vector<IntShift>& shifts, int w, int h, std::vector<std::uint16_t>& nIn) {
  std::vector<int> diff(std::size_t(w + 1) * h, 0);
  for (const auto& s : shifts) {
    const int xlo = std::max(0, -s.dx), xhi = std::min(w, w - s.dx);
    if (xlo >= xhi) continue;
    for (int y = std::max(0, -s.dy); y < std::min(h, h - s.dy); ++y) {
      ++diff[std::size_t(y) * (w + 1) + xlo];
      --diff[std::size_t(y) * (w + 1) + xhi];
    }
  }
  nIn.assign(std::size_t(w) * h, 0);
  for (int y = 0; y < h; ++y) {
    int c = 0;
    for (int x = 0; x < w; ++x)
      nIn[std::size_t(y) * w + x] = std::uint16_t(c += diff[std::size_t(y) * (w + 1) + x]);
  }
}

}  // namespace

int fftFriendlySize(int n) {
  const int multiple = n >= 64 ? 16 : 2;
  for (int m = std::max(multiple, n + (multiple - n % multiple) % multiple);; m += multiple) {
    int r = m;
    for (int p : {2, 3, 5})
      while (r % p == 0)
        r /= p;
    if (r == 1) return m;
  }
}

StackResult stackCsa(const FrameCube& cube, const std::vector<double>& offsetsS, Velocity v,
                     ProgressSink& progress, CancelToken& cancel, const CsaOptions& o) {
  if (cube.empty()) throw InputError("CSA stack: the cube has no frames");
  if (cube.frameCount() > 65535)
    throw InputError("CSA stack: " + std::to_string(cube.frameCount()) + " frames exceed the 65535 of N_in");
  if (offsetsS.size() != cube.frameCount())
    throw InputError("CSA stack: " + std::to_string(offsetsS.size()) + " time offsets for " +
                     std::to_string(cube.frameCount()) + " frames");
  const int w = cube.width(), h = cube.height();
  const std::vector<PixelOffset> reg = cube.frameOffsets();
  const std::vector<IntShift> shifts = ipsaShifts(offsetsS, v, reg);
  // Frames shifted entirely out of the image are skipped; the others set the padding.
  std::vector<std::size_t> used;
  double maxX = 0.0, maxY = 0.0;
  for (std::size_t n = 0; n < shifts.size(); ++n) {
    if (std::abs(shifts[n].dx) >= w || std::abs(shifts[n].dy) >= h) continue;
    used.push_back(n);
    maxX = std::max(maxX, std::fabs(reg[n].x + v.vx * offsetsS[n]));
    maxY = std::max(maxY, std::fabs(reg[n].y + v.vy * offsetsS[n]));
  }
  const int margin = std::max(0, o.marginPx);
  const int nx = fftFriendlySize(w + int(std::ceil(maxX)) + margin);
  const int ny = fftFriendlySize(h + int(std::ceil(maxY)) + margin);
  const int hx = nx / 2 + 1;
  const std::size_t nCplx = std::size_t(hx) * ny;
  const PlanPair plans = fftw::plans2d(nx, ny, o.measurePlans);

  const std::size_t workers = std::max<std::size_t>(1, std::min<std::size_t>(workerCount(), used.size()));
  std::vector<CplxBuf> accs(workers);
  std::atomic<std::size_t> done{0};
  progress.report(0.0, "CSA stack");
  parallelFor(workers, 1, [&](std::size_t b, std::size_t e) {
    for (std::size_t wk = b; wk < e; ++wk) {
      RealBuf in = allocReal(std::size_t(nx) * ny);
      CplxBuf spec = allocCplx(nCplx);
      accs[wk] = allocCplx(nCplx);
      std::memset(in.get(), 0, sizeof(float) * std::size_t(nx) * ny);
      std::memset(accs[wk].get(), 0, sizeof(fftwf_complex) * nCplx);
      std::vector<std::complex<float>> px, py, row;
      for (std::size_t i = wk * used.size() / workers; i < (wk + 1) * used.size() / workers; ++i) {
        cancel.throwIfCancelled();
        const std::size_t n = used[i];
        const float* f = cube.frame(n);
        for (int y = 0; y < h; ++y)
          std::memcpy(in.get() + std::size_t(y) * nx, f + std::size_t(y) * w, sizeof(float) * w);
        fftwf_execute_dft_r2c(plans.forward, in.get(), spec.get());
        phaseRamp(nx, hx, reg[n].x + v.vx * offsetsS[n], px);
        phaseRamp(ny, ny, reg[n].y + v.vy * offsetsS[n], py);
        accumulateShifted(spec.get(), accs[wk].get(), hx, ny, px, py, row);
        const std::size_t d = ++done;
        if (d % 16 == 0) progress.report(0.95 * double(d) / double(used.size()), "CSA stack");
      }
    }
  });
  cancel.throwIfCancelled();
  fftwf_complex* total = accs[0].get();
  for (std::size_t wk = 1; wk < workers; ++wk)
    for (std::size_t i = 0; i < nCplx; ++i) {
      total[i][0] += accs[wk][i][0];
      total[i][1] += accs[wk][i][1];
    }
  RealBuf out = allocReal(std::size_t(nx) * ny);
  fftwf_execute_dft_c2r(plans.inverse, total, out.get());
  StackResult r;
  r.sum = Image(w, h);
  const float scale = 1.0f / (float(nx) * float(ny));
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      r.sum.at(x, y) = out[std::size_t(y) * nx + x] * scale;
  countFrames(shifts, w, h, r.nIn);
  r.velocity = v;
  r.tRefMjd = cube.tRefMjd();
  r.mode = search::StackMode::Csa;
  progress.report(1.0, "CSA stack");
  return r;
}

StackResult stackCsa(const FrameCube& cube, Velocity v, ProgressSink& progress, CancelToken& cancel,
                     const CsaOptions& o) {
  if (cube.empty()) throw InputError("CSA stack: the cube has no frames");
  return stackCsa(cube, cube.timeOffsetsS(), v, progress, cancel, o);
}

Image shiftImage(const Image& in, double dx, double dy, const CsaOptions& o) {
  if (in.empty()) throw InputError("shifting an image: the image is empty");
  FrameCube one(in.width, in.height, 1);
  std::copy(in.pixels.begin(), in.pixels.end(), one.pixels().begin());
  NullProgress progress;
  CancelToken cancel;
  return stackCsa(one, std::vector<double>{1.0}, Velocity{dx, dy}, progress, cancel, o).sum;
}

}  // namespace st::stack

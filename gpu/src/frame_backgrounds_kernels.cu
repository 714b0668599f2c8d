// Kernels of frame_backgrounds.hpp: SEP's per-mesh statistics and its background spline on the device. The
// arithmetic follows SEP 1.2's background.c operation by operation (float where SEP is float, double where
// it promotes to double), with the _rn intrinsics so that nvcc fuses nothing the host does not.
#include <cstdint>

#include "cuda_check.hpp"
#include "frame_backgrounds.hpp"

namespace st::gpu {
namespace {

constexpr int kMeshThreads = 256;
constexpr int kBinsPerThread = kSepMaxLevels / kMeshThreads;  // 16

struct Sums {
  double s, ss;
  long long c;
};

// Block sum in a fixed order (each thread's strided samples in order, then a fixed tree).
__device__ Sums blockSums(Sums v, Sums* scratch) {
  scratch[threadIdx.x] = v;
  __syncthreads();
  for (int half = kMeshThreads / 2; half > 0; half /= 2) {
    if (threadIdx.x < half) {
      scratch[threadIdx.x].s = __dadd_rn(scratch[threadIdx.x].s, scratch[threadIdx.x + half].s);
      scratch[threadIdx.x].ss = __dadd_rn(scratch[threadIdx.x].ss, scratch[threadIdx.x + half].ss);
      scratch[threadIdx.x].c += scratch[threadIdx.x + half].c;
    }
    __syncthreads();
  }
  const Sums out = scratch[0];
  __syncthreads();
  return out;
}

struct IntSums {
  long long h, hi, hii;
};

__device__ IntSums blockIntSums(IntSums v, IntSums* scratch) {
  scratch[threadIdx.x] = v;
  __syncthreads();
  for (int half = kMeshThreads / 2; half > 0; half /= 2) {
    if (threadIdx.x < half) {
      scratch[threadIdx.x].h += scratch[threadIdx.x + half].h;
      scratch[threadIdx.x].hi += scratch[threadIdx.x + half].hi;
      scratch[threadIdx.x].hii += scratch[threadIdx.x + half].hii;
    }
    __syncthreads();
  }
  const IntSums out = scratch[0];
  __syncthreads();
  return out;
}

// mean, sigma of SEP's backstat from the sums: mean = s / n, sigma = sqrt(ss / n - mean^2) (0 if not > 0).
__device__ void meanSigma(const Sums& t, double& mean, double& sigma) {
  const double n = static_cast<double>(t.c);
  mean = __ddiv_rn(t.s, n);
  const double sig = __dsub_rn(__ddiv_rn(t.ss, n), __dmul_rn(mean, mean));
  sigma = sig > 0.0 ? sqrt(sig) : 0.0;
}

struct MeshState {
  int bad;
  float lcut, hcut;
  float mean, sigma, qscale, qzero, cste;
  int nlevels;
  // backguess
  int lo, hi, go;
  double sig, sig1, mea, med;
};

// One block per (frame, mesh): backstat, backhisto and backguess of SEP for that mesh.
__global__ void __launch_bounds__(kMeshThreads) sepMeshKernel(SepMeshLaunch p) {
  __shared__ int hist[kSepMaxLevels];
  __shared__ int prefix[kSepMaxLevels + 1];  // prefix[k] = hist[0] + ... + hist[k - 1]
  __shared__ Sums scratch[kMeshThreads];
  __shared__ IntSums iscratch[kMeshThreads];
  __shared__ int carry[kMeshThreads];
  __shared__ MeshState st;
  const int nb = p.nx * p.ny;
  const long long block = blockIdx.x;
  const int n = static_cast<int>(block / nb), m = static_cast<int>(block % nb);
  const int i = m % p.nx, j = m / p.nx;
  // SEP's last column and row of meshes take what is left of the frame (lastbite, npix % bufsize).
  const int mw = (i == p.nx - 1 && p.width % p.bw) ? p.width % p.bw : p.bw;
  const int mh = (j == p.ny - 1 && p.height % p.bh) ? p.height % p.bh : p.bh;
  const int x0 = i * p.bw, y0 = j * p.bh;
  const std::size_t frameOff = static_cast<std::size_t>(n) * p.width * p.height;
  const float* f = p.pix + frameOff;
  const std::uint8_t* mk = p.mask ? p.mask + frameOff : nullptr;
  const int total = mw * mh;
  auto index = [&](int l) { return static_cast<std::size_t>(y0 + l / mw) * p.width + x0 + l % mw; };
  const std::size_t out = static_cast<std::size_t>(n) * nb + m;

  // backstat, first pass: every unmasked sample above -BIG.
  Sums a{0.0, 0.0, 0};
  for (int l = threadIdx.x; l < total; l += kMeshThreads) {
    const std::size_t q = index(l);
    const float v = f[q];
    if ((!mk || mk[q] == 0) && static_cast<double>(v) > -kSepBig) {
      const double d = v;
      a.s = __dadd_rn(a.s, d);
      a.ss = __dadd_rn(a.ss, __dmul_rn(d, d));
      ++a.c;
    }
  }
  const Sums t1 = blockSums(a, scratch);
  if (threadIdx.x == 0) {
    st.bad = static_cast<float>(t1.c) < static_cast<float>(static_cast<double>(mw * mh) * 0.5);
    if (!st.bad) {
      double mean, sigma;
      meanSigma(t1, mean, sigma);
      st.lcut = static_cast<float>(__dsub_rn(mean, __dmul_rn(2.0, sigma)));
      st.hcut = static_cast<float>(__dadd_rn(mean, __dmul_rn(2.0, sigma)));
    }
  }
  __syncthreads();
  if (st.bad) {
    if (threadIdx.x == 0) {
      p.back[out] = static_cast<float>(-kSepBig);
      p.sigma[out] = static_cast<float>(-kSepBig);
    }
    return;
  }
  // Second pass: the samples within the 2-sigma cuts.
  const float lcut = st.lcut, hcut = st.hcut;
  a = Sums{0.0, 0.0, 0};
  for (int l = threadIdx.x; l < total; l += kMeshThreads) {
    const std::size_t q = index(l);
    const float v = f[q];
    if ((!mk || mk[q] == 0) && v <= hcut && v >= lcut) {
      const double d = v;
      a.s = __dadd_rn(a.s, d);
      a.ss = __dadd_rn(a.ss, __dmul_rn(d, d));
      ++a.c;
    }
  }
  const Sums t2 = blockSums(a, scratch);
  if (threadIdx.x == 0) {
    double mean, sigma;
    meanSigma(t2, mean, sigma);
    st.mean = static_cast<float>(mean);
    st.sigma = static_cast<float>(sigma);
    int nlevels = static_cast<int>(__dadd_rn(__dmul_rn(p.step, static_cast<double>(t2.c)), 1.0));
    if (nlevels > kSepMaxLevels) nlevels = kSepMaxLevels;
    st.nlevels = nlevels;
    st.qscale = sigma > 0.0
                    ? static_cast<float>(__ddiv_rn(__dmul_rn(10.0, sigma), static_cast<double>(nlevels)))
                    : 1.0f;
    st.qzero = static_cast<float>(__dsub_rn(mean, __dmul_rn(5.0, sigma)));
    // cste = 0.499999 - qzero / qscale: the quotient in float, the difference in double, stored as float.
    st.cste = static_cast<float>(__dsub_rn(0.499999, static_cast<double>(__fdiv_rn(st.qzero, st.qscale))));
  }
  for (int k = threadIdx.x; k < kSepMaxLevels; k += kMeshThreads)
    hist[k] = 0;
  __syncthreads();
  // backhisto: bin = (int)(v / qscale + cste) in float; SEP's (int) of a NaN is INT_MIN on x86 (no bin), the
  // device's 0, so NaN is left out here explicitly.
  const int nlevels = st.nlevels;
  const float qscale = st.qscale, cste = st.cste;
  for (int l = threadIdx.x; l < total; l += kMeshThreads) {
    const std::size_t q = index(l);
    const float b = __fadd_rn(__fdiv_rn(f[q], qscale), cste);
    if (b != b) continue;
    const int bin = __float2int_rz(b);
    if ((!mk || mk[q] == 0) && bin < nlevels && bin >= 0) atomicAdd(&hist[bin], 1);
  }
  __syncthreads();
  // Prefix counts of the histogram: each thread 16 bins, then a scan of the threads' totals.
  {
    const int k0 = threadIdx.x * kBinsPerThread;
    int mine = 0;
    for (int k = 0; k < kBinsPerThread; ++k)
      mine += hist[k0 + k];
    carry[threadIdx.x] = mine;
    __syncthreads();
    for (int off = 1; off < kMeshThreads; off <<= 1) {
      const int add = threadIdx.x >= off ? carry[threadIdx.x - off] : 0;
      __syncthreads();
      carry[threadIdx.x] += add;
      __syncthreads();
    }
    int run = carry[threadIdx.x] - mine;
    for (int k = 0; k < kBinsPerThread; ++k) {
      prefix[k0 + k] = run;
      run += hist[k0 + k];
    }
    if (threadIdx.x == kMeshThreads - 1) prefix[kSepMaxLevels] = run;
  }
  // backguess: the clipped histogram's mean, median and sigma, iterated.
  const int nlevelsm1 = nlevels - 1;
  if (threadIdx.x == 0) {
    st.lo = 0;
    st.hi = nlevelsm1;
    st.sig = 10.0 * nlevelsm1;
    st.sig1 = 1.0;
    st.mea = st.med = static_cast<double>(st.mean);
    st.go = 100;  // SEP's `n`
  }
  __syncthreads();
  for (;;) {
    // for (n = 100; n-- && sig >= 0.1 && fabs(sig / sig1 - 1.0) > EPS;)
    if (threadIdx.x == 0) {
      const bool more =
          st.go-- != 0 && st.sig >= 0.1 && fabs(__dsub_rn(__ddiv_rn(st.sig, st.sig1), 1.0)) > 1e-4;
      if (!more) st.go = -1000;
    }
    __syncthreads();
    if (st.go < -100) break;
    const int lo = st.lo, hi = st.hi;
    IntSums v{0, 0, 0};
    for (int k = lo + static_cast<int>(threadIdx.x); k <= hi; k += kMeshThreads) {
      const long long h = hist[k];
      v.h += h;
      v.hi += h * k;
      v.hii += h * k * k;
    }
    const IntSums s = blockIntSums(v, iscratch);  // exact: SEP's double sums of integers are exact too
    if (threadIdx.x == 0) {
      st.sig1 = st.sig;
      // SEP's walk: lowsum from bin lo up, highsum from bin hi down, the smaller side advancing (high on a
      // tie) for hi - lo + 1 steps. It leaves the low side past bin lo + a - 1, a the first index with
      // P_a + P_(a+1) >= T (P the prefix counts from lo, T their total), and highsum = T - P_a.
      int hilow = lo, hihigh = hi;
      long long lowsum = 0, highsum = 0;
      const int count = hi - lo + 1;
      if (count > 0) {
        const long long base = prefix[lo], T = static_cast<long long>(prefix[hi + 1]) - base;
        int l = 0, r = count - 1;  // r satisfies the condition (P_count = T)
        while (l < r) {
          const int mid = (l + r) / 2;
          if ((prefix[lo + mid] - base) + (prefix[lo + mid + 1] - base) >= T)
            r = mid;
          else
            l = mid + 1;
        }
        hilow = lo + l;
        hihigh = lo + l - 1;
        lowsum = prefix[lo + l] - base;
        highsum = T - lowsum;
      }
      double med = 0.0;
      if (hihigh >= 0) {
        const int hl = hilow < kSepMaxLevels ? hist[hilow] : 0, hh = hist[hihigh];
        med = __dadd_rn(__dadd_rn(static_cast<double>(hihigh), 0.5),
                        __ddiv_rn(__dsub_rn(static_cast<double>(highsum), static_cast<double>(lowsum)),
                                  __dmul_rn(2.0, static_cast<double>(hl > hh ? hl : hh))));
      }
      double mea = static_cast<double>(s.hi), sig = static_cast<double>(s.hii);
      if (s.h) {
        const double sum = static_cast<double>(s.h);
        mea = __ddiv_rn(mea, sum);
        sig = __dsub_rn(__ddiv_rn(sig, sum), __dmul_rn(mea, mea));
      }
      sig = sig > 0.0 ? sqrt(sig) : 0.0;
      double ftemp = __dsub_rn(med, __dmul_rn(3.0, sig));
      st.lo = ftemp > 0.0 ? __double2int_rz(__dadd_rn(ftemp, 0.5)) : 0;
      ftemp = __dadd_rn(med, __dmul_rn(3.0, sig));
      st.hi = ftemp < nlevelsm1 ? __double2int_rz(ftemp > 0.0 ? __dadd_rn(ftemp, 0.5) : __dsub_rn(ftemp, 0.5))
                                : nlevelsm1;
      st.mea = mea;
      st.sig = sig;
      st.med = med;
    }
    __syncthreads();
  }
  if (threadIdx.x == 0) {
    const double qzero = st.qzero, qscale = st.qscale, sig = st.sig, mea = st.mea, med = st.med;
    double mode;
    if (fabs(sig) > 0.0)
      mode = fabs(__ddiv_rn(__dsub_rn(mea, med), sig)) < 0.3
                 ? __dadd_rn(qzero, __dmul_rn(__dsub_rn(__dmul_rn(2.5, med), __dmul_rn(1.5, mea)), qscale))
                 : __dadd_rn(qzero, __dmul_rn(med, qscale));
    else
      mode = __dadd_rn(qzero, __dmul_rn(mea, qscale));
    p.back[out] = static_cast<float>(mode);
    p.sigma[out] = static_cast<float>(__dmul_rn(sig, qscale));
  }
}

constexpr int kRowThreads = 128;

// One block per (frame, row): SEP's bkg_line_flt_internal for that row, subtracted, the level restored.
__global__ void __launch_bounds__(kRowThreads) sepSubtractKernel(SepSubtractLaunch p) {
  extern __shared__ float sh[];
  float* node = sh;          // [nx]
  float* dnode = sh + p.nx;  // [nx]
  float* u = sh + 2 * p.nx;  // [nx]
  const long long block = blockIdx.x;
  const int n = static_cast<int>(block / p.height), y = static_cast<int>(block % p.height);
  const std::size_t nb = static_cast<std::size_t>(p.nx) * p.ny;
  const float* back = p.back + static_cast<std::size_t>(n) * nb;
  const float* dback = p.dback + static_cast<std::size_t>(n) * nb;
  if (p.ny > 1) {
    const SepRow r = p.rows[y];
    const float* blo = back + static_cast<std::size_t>(r.yl) * p.nx;
    const float* dblo = dback + static_cast<std::size_t>(r.yl) * p.nx;
    for (int k = threadIdx.x; k < p.nx; k += kRowThreads)
      node[k] = __fadd_rn(__fadd_rn(__fadd_rn(__fmul_rn(r.cdy, blo[k]), __fmul_rn(r.dy, blo[k + p.nx])),
                                    __fmul_rn(r.cdy3, dblo[k])),
                          __fmul_rn(r.dy3, dblo[k + p.nx]));
    __syncthreads();
    if (threadIdx.x == 0 && p.nx > 1) {
      // The x second derivatives ("natural" spline), in SEP's order.
      dnode[0] = u[0] = 0.0f;
      for (int k = 1; k < p.nx - 1; ++k) {
        float temp = __fdiv_rn(-1.0f, __fadd_rn(dnode[k - 1], 4.0f));
        dnode[k] = temp;
        const float curv = __fsub_rn(__fadd_rn(node[k + 1], node[k - 1]), __fmul_rn(2.0f, node[k]));
        temp = __fmul_rn(temp, __fsub_rn(u[k - 1], __fmul_rn(6.0f, curv)));
        u[k] = temp;
      }
      dnode[p.nx - 1] = 0.0f;
      for (int k = p.nx - 1; k >= 2; --k)
        dnode[k - 1] = static_cast<float>(
            __ddiv_rn(static_cast<double>(__fadd_rn(__fmul_rn(dnode[k - 1], dnode[k]), u[k - 1])), 6.0));
    }
  } else {
    for (int k = threadIdx.x; k < p.nx; k += kRowThreads) {
      node[k] = back[k];
      dnode[k] = dback[k];
    }
  }
  __syncthreads();
  float* row = p.pix + (static_cast<std::size_t>(n) * p.height + y) * p.width;
  for (int x = threadIdx.x; x < p.width; x += kRowThreads) {
    float line;
    if (p.nx > 1) {
      const SepColumn c = p.cols[x];
      const int k = c.node;
      line = __fadd_rn(__fmul_rn(c.cdx, __fadd_rn(node[k], __fmul_rn(c.a, dnode[k]))),
                       __fmul_rn(c.dx, __fadd_rn(node[k + 1], __fmul_rn(c.b, dnode[k + 1]))));
    } else {
      line = node[0];
    }
    row[x] = __fadd_rn(__fsub_rn(row[x], line), p.restored);
  }
}

// One thread per pixel: core/detect/hot_pixels.cpp's block sums in its order and arithmetic.
__global__ void hotPixelExcessKernel(const float* pix, const std::uint8_t* mask, std::size_t np, int nf,
                                     int blocks, double background, float* minExcess) {
  const std::size_t i = static_cast<std::size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i >= np) return;
  float lowest = 1e30f;
  for (int b = 0; b < blocks; ++b) {
    const std::size_t n0 = static_cast<std::size_t>(nf) * b / blocks;
    const std::size_t n1 = static_cast<std::size_t>(nf) * (b + 1) / blocks;
    double s = 0.0;
    unsigned c = 0;
    for (std::size_t n = n0; n < n1; ++n) {
      const bool in = !mask || !mask[n * np + i];
      s = __dadd_rn(s, in ? static_cast<double>(pix[n * np + i]) : 0.0);
      c += in;
    }
    const float e =
        c ? static_cast<float>(__dsub_rn(__ddiv_rn(s, static_cast<double>(c)), background)) : 0.0f;
    lowest = e < lowest ? e : lowest;  // std::min(lowest, e)
  }
  minExcess[i] = lowest;
}

}  // namespace

void launchHotPixelExcess(const float* pix, const std::uint8_t* mask, std::size_t framePixels, int nf,
                          int blocks, double background, float* minExcess, cudaStream_t s) {
  if (framePixels == 0) return;
  const unsigned grid = static_cast<unsigned>((framePixels + 255) / 256);
  hotPixelExcessKernel<<<grid, 256, 0, s>>>(pix, mask, framePixels, nf, blocks, background, minExcess);
  checkLaunch("hotPixelExcessKernel");
}

namespace {

__global__ void pixelCalibrationKernel(PixelCalibrationLaunch p) {
  const std::size_t k = blockIdx.x * static_cast<std::size_t>(blockDim.x) + threadIdx.x;
  if (k >= p.nf * p.np) return;
  const std::size_t n = k / p.np, i = k - n * p.np;
  float v = __fsub_rn(p.pix[k], __ldg(p.overscan + n));
  if (p.bias) v = __fsub_rn(v, __ldg(p.bias + i));
  if (p.darkPerS) v = __fsub_rn(v, __fmul_rn(__ldg(p.darkPerS + i), __ldg(p.darkSeconds + n)));
  if (p.flat) v = __fdiv_rn(v, __ldg(p.flat + i));
  p.pix[k] = v;
}

}  // namespace

void launchPixelCalibration(const PixelCalibrationLaunch& p, cudaStream_t s) {
  const std::size_t total = p.nf * p.np;
  if (total == 0) return;
  constexpr int kThreads = 256;
  pixelCalibrationKernel<<<static_cast<unsigned>((total + kThreads - 1) / kThreads), kThreads, 0, s>>>(p);
  checkLaunch("pixelCalibrationKernel");
}

void launchSepMeshes(const SepMeshLaunch& p, cudaStream_t s) {
  const long long blocks = static_cast<long long>(p.nf) * p.nx * p.ny;
  if (blocks == 0) return;
  sepMeshKernel<<<static_cast<unsigned>(blocks), kMeshThreads, 0, s>>>(p);
  checkLaunch("sepMeshKernel");
}

void launchSepSubtract(const SepSubtractLaunch& p, cudaStream_t s) {
  const long long blocks = static_cast<long long>(p.nf) * p.height;
  if (blocks == 0) return;
  const std::size_t shared = 3 * sizeof(float) * static_cast<std::size_t>(p.nx);
  sepSubtractKernel<<<static_cast<unsigned>(blocks), kRowThreads, shared, s>>>(p);
  checkLaunch("sepSubtractKernel");
}

}  // namespace st::gpu

#pragma once
// The mixed-radix complex FFT in shared memory that the phase correlations (the sky rate's and registration's
// sampled links) run on the device: a decimation-in-time transform, its input in mixed-radix digit-reversed
// order (reversedPos), its stages of radix 4, 2, 3 or 5 in place, one block per row or column. Device code
// for the .cu files that include it.
#include <cuda_runtime.h>

#include <cstddef>
#include <string>

#include "cuda_check.hpp"
#include "phase_correlation_kernels.hpp"

namespace st::gpu::fft {

__device__ __forceinline__ float2 cmul(float2 a, float2 b) {
  return make_float2(a.x * b.x - a.y * b.y, a.x * b.y + a.y * b.x);
}
__device__ __forceinline__ float2 cadd(float2 a, float2 b) {
  return make_float2(a.x + b.x, a.y + b.y);
}
__device__ __forceinline__ float2 csub(float2 a, float2 b) {
  return make_float2(a.x - b.x, a.y - b.y);
}

// Where element i of the input goes so that the stages, first to last, leave the transform in natural order:
// the last stage's radix splits i first (i mod r), its digit the most significant of the position.
__device__ inline int reversedPos(int i, const PhaseFftAxis& a) {
  int pos = 0, len = a.n;
  for (int t = a.stages - 1; t >= 0; --t) {
    const int r = a.radix[t];
    const int q = i % r;
    i /= r;
    len /= r;
    pos += q * len;
  }
  return pos;
}

// One stage: n / R butterflies, each combining R transforms of length m into one of length m R.
template <int R>
__device__ void radixStage(float2* s, const PhaseFftAxis& a, int m, bool inverse) {
  const int n = a.n, len = m * R, step = n / len, root = n / R;
  for (int j = threadIdx.x; j < n / R; j += blockDim.x) {
    const int k = j % m;
    const int base = (j / m) * len + k;
    float2 z[R];
#pragma unroll
    for (int q = 0; q < R; ++q) {
      z[q] = s[base + q * m];
      if (q > 0 && k > 0) {
        float2 w = a.twiddle[k * q * step];
        if (inverse) w.y = -w.y;
        z[q] = cmul(z[q], w);
      }
    }
    if constexpr (R == 2) {
      s[base] = cadd(z[0], z[1]);
      s[base + m] = csub(z[0], z[1]);
    } else if constexpr (R == 4) {
      const float2 e = cadd(z[0], z[2]), f = csub(z[0], z[2]);
      const float2 g = cadd(z[1], z[3]), t = csub(z[1], z[3]);
      // -i t forward, +i t inverse
      const float2 rt = inverse ? make_float2(-t.y, t.x) : make_float2(t.y, -t.x);
      s[base] = cadd(e, g);
      s[base + m] = cadd(f, rt);
      s[base + 2 * m] = csub(e, g);
      s[base + 3 * m] = csub(f, rt);
    } else {
#pragma unroll
      for (int p = 0; p < R; ++p) {
        float2 y = z[0];
#pragma unroll
        for (int q = 1; q < R; ++q) {
          float2 w = a.twiddle[((p * q) % R) * root];
          if (inverse) w.y = -w.y;
          y = cadd(y, cmul(z[q], w));
        }
        s[base + p * m] = y;
      }
    }
  }
  __syncthreads();
}

// The transform of s (a.n complexes, in reversedPos order on entry, natural order on return). Every thread of
// the block must call it.
__device__ inline void fftShared(float2* s, const PhaseFftAxis& a, bool inverse) {
  int m = 1;
  for (int st = 0; st < a.stages; ++st) {
    switch (a.radix[st]) {
      case 2:
        radixStage<2>(s, a, m, inverse);
        break;
      case 3:
        radixStage<3>(s, a, m, inverse);
        break;
      case 4:
        radixStage<4>(s, a, m, inverse);
        break;
      default:
        radixStage<5>(s, a, m, inverse);
        break;
    }
    m *= a.radix[st];
  }
}

/// Opts `kernel` in to `bytes` of dynamic shared memory where that and its static shared memory pass the
/// default 48 KB a block (host code); `what` names the kernels in the error.
inline void allowSharedBytes(const void* kernel, std::size_t bytes, const char* what) {
  cudaFuncAttributes attr{};
  check(cudaFuncGetAttributes(&attr, kernel), (std::string("cudaFuncGetAttributes(") + what + ")").c_str());
  if (bytes + attr.sharedSizeBytes > 48 * 1024)
    check(cudaFuncSetAttribute(kernel, cudaFuncAttributeMaxDynamicSharedMemorySize, static_cast<int>(bytes)),
          (std::string("cudaFuncSetAttribute(") + what + " shared memory)").c_str());
}

}  // namespace st::gpu::fft

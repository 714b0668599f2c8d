// Stacks of the cube at one velocity, for live scrubbing (ARCHITECTURE.md "IPSA").
// Frames are split into groups; each group sums into its own plane (deterministic), then one pass adds the
// planes. IPSA: integer shifts round(v dt), out-of-frame samples excluded.
#include <cuda_runtime.h>

#include "cuda_check.hpp"
#include "kernel_params.hpp"

namespace st::gpu {
namespace {

__global__ void stackGroupsKernel(StackLaunch p) {
  const int x = blockIdx.x * blockDim.x + threadIdx.x;
  const int y = blockIdx.y;
  const int g = blockIdx.z;
  if (x >= p.width) return;
  const int per = (p.frameCount + p.groups - 1) / p.groups;
  const int n0 = g * per;
  const int n1 = min(p.frameCount, n0 + per);
  const long long plane = static_cast<long long>(p.width) * p.height;
  float sum = 0.0f;
  for (int n = n0; n < n1; ++n) {
    const float* f = p.frames + n * plane;
    const int sx = x + p.shiftX[n];
    const int sy = y + p.shiftY[n];
    if (sx >= 0 && sx < p.width && sy >= 0 && sy < p.height)
      sum += f[static_cast<long long>(sy) * p.width + sx];
  }
  p.partial[g * plane + static_cast<long long>(y) * p.width + x] = sum;
}

__global__ void sumGroupsKernel(StackLaunch p) {
  const long long plane = static_cast<long long>(p.width) * p.height;
  const long long i = blockIdx.x * static_cast<long long>(blockDim.x) + threadIdx.x;
  if (i >= plane) return;
  float sum = 0.0f;
  for (int g = 0; g < p.groups; ++g)
    sum += p.partial[g * plane + i];
  p.out[i] = sum;
}

}  // namespace

void launchStack(const StackLaunch& p, cudaStream_t stream) {
  const dim3 grid((p.width + 127) / 128, p.height, p.groups);
  stackGroupsKernel<<<grid, 128, 0, stream>>>(p);
  checkLaunch("stackGroupsKernel");
  const long long plane = static_cast<long long>(p.width) * p.height;
  sumGroupsKernel<<<static_cast<int>((plane + 255) / 256), 256, 0, stream>>>(p);
  checkLaunch("sumGroupsKernel");
}

}  // namespace st::gpu

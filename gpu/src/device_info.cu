// Device enumeration for the CUDA backend. Placeholder until the CUDA backend lands: reports devices only.
#include <cuda_runtime.h>

#include <string>

#include "st/gpu/cuda_backend.hpp"

namespace st::gpu {

std::string deviceSummary() {
  int count = 0;
  const cudaError_t err = cudaGetDeviceCount(&count);
  if (err != cudaSuccess) return std::string("no CUDA device: ") + cudaGetErrorString(err);
  if (count == 0) return "no CUDA device";
  std::string out;
  for (int i = 0; i < count; ++i) {
    cudaDeviceProp prop{};
    if (cudaGetDeviceProperties(&prop, i) != cudaSuccess) continue;
    out += std::to_string(i) + ": " + prop.name + "\n";
  }
  return out;
}

std::unique_ptr<search::SearchBackend> makeCudaBackend(std::string& whyNot) {
  whyNot = "the CUDA backend is not implemented yet";
  return nullptr;
}

}  // namespace st::gpu

#include "device_info.hpp"

#include <cuda_runtime.h>

#include <cstdio>

#include "st/gpu/cuda_backend.hpp"

namespace st::gpu {

std::vector<DeviceInfo> usableDevices(std::string& whyNot) {
  int count = 0;
  const cudaError_t err = cudaGetDeviceCount(&count);
  if (err != cudaSuccess) {
    whyNot = std::string("no usable CUDA driver or device: ") + cudaGetErrorString(err);
    cudaGetLastError();  // clear the sticky error for later calls
    return {};
  }
  if (count == 0) {
    whyNot = "no CUDA device is visible (CUDA_VISIBLE_DEVICES?)";
    return {};
  }
  std::vector<DeviceInfo> out;
  std::string skipped;
  for (int i = 0; i < count; ++i) {
    cudaDeviceProp prop{};
    if (cudaGetDeviceProperties(&prop, i) != cudaSuccess) continue;
    if (prop.major < 9) {
      skipped += std::string(skipped.empty() ? "" : "; ") + "device " + std::to_string(i) + " (" + prop.name +
                 ") is sm_" + std::to_string(prop.major * 10 + prop.minor) +
                 ", this build needs sm_90 or newer";
      continue;
    }
    if (cudaSetDevice(i) != cudaSuccess || cudaFree(nullptr) != cudaSuccess) {
      skipped +=
          std::string(skipped.empty() ? "" : "; ") + "device " + std::to_string(i) + " cannot be initialised";
      cudaGetLastError();
      continue;
    }
    out.push_back(DeviceInfo{i, prop.name, prop.totalGlobalMem, prop.major * 10 + prop.minor});
  }
  if (out.empty()) whyNot = skipped.empty() ? "no usable CUDA device" : skipped;
  return out;
}

std::string deviceSummary() {
  int count = 0;
  const cudaError_t err = cudaGetDeviceCount(&count);
  if (err != cudaSuccess) return std::string("no CUDA device: ") + cudaGetErrorString(err);
  if (count == 0) return "no CUDA device";
  std::string out;
  for (int i = 0; i < count; ++i) {
    cudaDeviceProp prop{};
    if (cudaGetDeviceProperties(&prop, i) != cudaSuccess) continue;
    char line[768];
    std::snprintf(line, sizeof(line), "%d: %s, %.1f GiB, sm_%d%d\n", i, prop.name,
                  static_cast<double>(prop.totalGlobalMem) / (1024.0 * 1024.0 * 1024.0), prop.major,
                  prop.minor);
    out += line;
  }
  return out;
}

}  // namespace st::gpu

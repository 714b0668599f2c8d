#pragma once
// Enumeration of the devices the CUDA backend can use (CUDA_VISIBLE_DEVICES is applied by the runtime).
#include <cstddef>
#include <string>
#include <vector>

namespace st::gpu {

struct DeviceInfo {
  int ordinal = 0;  ///< CUDA device ordinal (after CUDA_VISIBLE_DEVICES)
  std::string name;
  std::size_t totalBytes = 0;
  int computeCapability = 0;  ///< e.g. 90
};

/// Devices of compute capability 9.0 or newer that initialise; empty with `whyNot` set otherwise.
std::vector<DeviceInfo> usableDevices(std::string& whyNot);

}  // namespace st::gpu

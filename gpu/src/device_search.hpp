#pragma once
// The search on one device: uploads the cube (pinned staging, a copy stream overlapping the first
// velocity chunk's compute), runs the tiled kernel over chunks of velocity rows, and brings back only the
// per-velocity maxima and the cells above threshold. When the cube does not fit in the memory allowed,
// frames are streamed in chunks and partial sums kept on the device per velocity chunk.
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "kernel_params.hpp"
#include "search_plan.hpp"
#include "st/common/progress.hpp"

namespace st::gpu {

struct DeviceResources;

struct TreeWorkspace;  // tree_search_device.hpp

struct DeviceJob {
  int device = 0;
  /// Streams and staging kept by the backend between searches (made on first use); null: made for this one.
  std::unique_ptr<DeviceResources>* resources = nullptr;
  int iyBegin = 0;  ///< grid rows [iyBegin, iyEnd) go to this device
  int iyEnd = 0;
  std::size_t memoryLimitBytes = 0;  ///< 0: what the device has free (less a reserve)
  std::size_t cellCapacity = 0;      ///< candidate buffer, cells
  std::size_t uploadChunkBytes = 0;  ///< resident cube: frames per upload step (0: kUploadChunkBytes)
  bool naiveKernel = false;          ///< the one-thread-per-(pixel, velocity) reference kernel instead
  int treeRootShape = 0;             ///< tree search: TreeRootLaunch::shape
  bool treeDirectPlain = false;      ///< tree search: TreeLevelLaunch::directPlain (benchmarks)
  bool profile = false;              ///< tree search: time each level of the first tile (for the note)
  /// Identity of the host cube (resident_cube.hpp cubeKey): the device's resident cube is used without an
  /// upload when it holds this one, else the cube is uploaded into it and kept. 0 = upload, keep nothing.
  std::uint64_t cubeKey = 0;
  /// Tree search: the device's workspace kept by the backend (null: made for this search and freed), and the
  /// plan's key (0: nothing kept; the workspace is made again when its key differs).
  TreeWorkspace* treeWorkspace = nullptr;
  std::uint64_t treePlanKey = 0;
};

struct DeviceOutcome {
  std::vector<unsigned long long> mapKeys;  ///< [iyEnd - iyBegin][nvx] packed maxima, 0 = no valid cell
  std::vector<DeviceCell> cells;            ///< cells above threshold (at most cellCapacity)
  std::uint64_t cellsAbove = 0;             ///< all cells above threshold (> cells.size() on overflow)
  std::string note;                         ///< how the work was tiled, for the log
  double kernelSeconds = 0.0;               ///< device time of the search kernels (events)
  double uploadSeconds = 0.0;               ///< device time of the cube's upload (tree search; events)
};

/// Runs `job` for `plan` over `frames` (N_f * W * H floats, host). `progress(fraction)` is called from
/// this thread; `cancel` (the user's) and `abort`
/// (another device failed) are polled between launches. Throws st::GpuError on any CUDA failure (out of
/// memory included) and st::Cancelled.
DeviceOutcome runOnDevice(const HostPlan& plan, const float* frames, const DeviceJob& job,
                          const std::function<void(double)>& progress, const CancelToken& cancel,
                          const std::atomic<bool>& abort);

}  // namespace st::gpu

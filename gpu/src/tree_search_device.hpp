#pragma once
// The tree search on one device: uploads the cube (it stays resident for the whole search), then for each
// of its tiles of rows runs the levels of the tree (tree_device_plan.hpp) and the root kernel, which reduces
// the velocity map and appends the cells above threshold on the device.
#include <atomic>
#include <cstdint>
#include <functional>

#include "cuda_check.hpp"
#include "device_search.hpp"
#include "search_plan.hpp"
#include "tree_device_plan.hpp"

namespace st::gpu {

/// What one device keeps between tree searches of the same plan (issue 16: re-search <= 60 ms): the two
/// partial-stack arenas (9.6 GiB for the paper's problem), the plan's tables and the cell buffer; made on
/// the device when `key` is not the plan's, kept by the backend while its searches use that plan on the same
/// resident cube, freed by clear() (an exact search, another cube or plan, a failure).
struct TreeWorkspace {
  std::uint64_t key = 0;  ///< the plan's key (CudaBackend::treePlanKey); 0 = nothing kept
  DeviceBuffer<float> arena[2];
  DeviceBuffer<TreeJob> jobs;
  DeviceBuffer<int4> segTab;
  DeviceBuffer<int2> rowJobs, rowTab;
  DeviceBuffer<int> shiftX, shiftY, frameIndex, cutPitch, colBase, rowBase;
  DeviceBuffer<long long> cutBase;
  DeviceBuffer<DeviceCell> cells;
  int reused = 0;  ///< searches that found it made (for notes and tests)
  /// Frees everything (the workspace's device must be current).
  void clear() { *this = TreeWorkspace(); }
  [[nodiscard]] std::size_t bytes() const {
    return arena[0].bytes() + arena[1].bytes() + jobs.bytes() + segTab.bytes() + rowJobs.bytes() +
           rowTab.bytes() + shiftX.bytes() + shiftY.bytes() + frameIndex.bytes() + cutPitch.bytes() +
           colBase.bytes() + rowBase.bytes() + cutBase.bytes() + cells.bytes();
  }
};

/// Device memory the tree search needs besides the cube: arenas, tables, map and cell buffer.
std::size_t treeDeviceBytes(const TreeDevicePlan& tree, const HostPlan& plan, std::size_t cellCapacity);

/// Runs tiles [tileBegin, tileEnd) of `tree` on job.device. `plan` gives N_in spans, 1/(sigma sqrt n),
/// threshold and minimum frames (as the exact search). mapKeys of the outcome cover the whole grid.
/// Throws st::GpuError (out of memory included), st::Cancelled.
DeviceOutcome runTreeOnDevice(const TreeDevicePlan& tree, const HostPlan& plan, const float* frames,
                              const DeviceJob& job, int tileBegin, int tileEnd,
                              const std::function<void(double)>& progress, const CancelToken& cancel,
                              const std::atomic<bool>& abort);

}  // namespace st::gpu

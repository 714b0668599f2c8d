#pragma once
// The tree search on one device: uploads the cube (it stays resident for the whole search), then for each
// of its tiles of rows runs the levels of the tree (tree_device_plan.hpp) and the root kernel, which reduces
// the velocity map and appends the cells above threshold on the device.
#include <atomic>
#include <functional>

#include "device_search.hpp"
#include "search_plan.hpp"
#include "tree_device_plan.hpp"

namespace st::gpu {

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

#include "tree_search_device.hpp"

#include <cstdio>
#include <memory>
#include <mutex>
#include <string>

#include "cuda_check.hpp"
#include "resident_cube.hpp"
#include "uploader.hpp"
#include "wall_phases.hpp"

namespace st::gpu {
namespace {

float elapsedSeconds(const Event& a, const Event& b) {
  float ms = 0.0f;
  ST_CUDA_CHECK(cudaEventElapsedTime(&ms, a.get(), b.get()));
  return ms * 1e-3f;
}

}  // namespace

std::size_t treeDeviceBytes(const TreeDevicePlan& tree, const HostPlan& plan, std::size_t cellCapacity) {
  return tree.arenaBytes() + tree.tableBytes() +
         (plan.spanX.size() + plan.spanY.size() + plan.maskX.size() + plan.maskY.size()) * sizeof(int) +
         plan.invNorm.size() * sizeof(float) + static_cast<std::size_t>(plan.nvx) * plan.nvy * 8 +
         cellCapacity * sizeof(DeviceCell) + 4096;
}

DeviceOutcome runTreeOnDevice(const TreeDevicePlan& tree, const HostPlan& plan, const float* frames,
                              const DeviceJob& job, int tileBegin, int tileEnd,
                              const std::function<void(double)>& progress, const CancelToken& cancel,
                              const std::atomic<bool>& abort) {
  auto poll = [&] {
    cancel.throwIfCancelled();
    if (abort.load(std::memory_order_relaxed)) throw Cancelled();
  };
  ST_CUDA_CHECK(cudaSetDevice(job.device));
  std::unique_ptr<DeviceResources> own;
  DeviceResources& res = ensureResources(job.resources ? *job.resources : own);
  const std::size_t plane = static_cast<std::size_t>(plan.width) * plan.height;
  const std::size_t cubeFloats = plane * static_cast<std::size_t>(plan.frameCount);
  Stream& compute = res.compute;
  Stream& copy = res.copy;
  // The device's resident cube (resident_cube.hpp): no upload when it holds this cube, else uploaded into it.
  ResidentSlot* slot = job.cubeKey != 0 ? &residentSlot(job.device) : nullptr;
  std::unique_lock<std::mutex> lock;
  if (slot) lock = std::unique_lock<std::mutex>(slot->mutex);
  const bool have = slot && slot->holds(job.cubeKey, cubeFloats);
  DeviceBuffer<float> ownCube;
  if (!have) {
    if (slot) slot->clear();
    (slot ? slot->cube : ownCube) = DeviceBuffer<float>(cubeFloats);
  }
  DeviceBuffer<float>& cube = slot ? slot->cube : ownCube;
  // Wall time of the host-side steps, for the note (the first search of a plan makes its workspace).
  WallPhases wall;
  // The arenas, the plan's tables and the cell buffer: kept from the last search of this plan, else made.
  TreeWorkspace local;
  TreeWorkspace& ws = job.treeWorkspace ? *job.treeWorkspace : local;
  const bool kept = job.treePlanKey != 0 && ws.key == job.treePlanKey;
  if (kept) {
    ++ws.reused;
  } else {
    ws.clear();
    for (int a = 0; a < 2; ++a)
      ws.arena[a] = DeviceBuffer<float>(tree.arenaFloats[a] + kTreeArenaSlack);
    ws.jobs = toDevice(tree.jobs);
    ws.segTab = toDevice(tree.segTab);
    ws.rowJobs = toDevice(tree.rowJobs);
    ws.rowTab = toDevice(tree.rowTab);
    ws.shiftX = toDevice(tree.shiftX);
    ws.shiftY = toDevice(tree.shiftY);
    ws.frameIndex = toDevice(tree.frameIndex);
    ws.cutPitch = toDevice(tree.cutPitch);
    ws.colBase = toDevice(tree.colBase);
    ws.rowBase = toDevice(tree.rowBase);
    ws.cutBase = toDevice(tree.cutBase);
    ws.key = job.treePlanKey;  // only once all of it is made
  }
  if (ws.cells.size() < std::max<std::size_t>(job.cellCapacity, 1))
    ws.cells = DeviceBuffer<DeviceCell>(std::max<std::size_t>(job.cellCapacity, 1));
  DeviceBuffer<float>* arena = ws.arena;
  DeviceBuffer<DeviceCell>& cells = ws.cells;
  DeviceBuffer<int> spanX = toDevice(plan.spanX), spanY = toDevice(plan.spanY);
  DeviceBuffer<unsigned> maskX = toDevice(plan.maskX), maskY = toDevice(plan.maskY);
  DeviceBuffer<float> invNorm = toDevice(plan.invNorm);
  const std::size_t nv = static_cast<std::size_t>(plan.nvx) * plan.nvy;
  DeviceBuffer<unsigned long long> mapKeys(nv), count(1);
  ST_CUDA_CHECK(cudaMemsetAsync(mapKeys.get(), 0, nv * 8, compute.get()));
  ST_CUDA_CHECK(cudaMemsetAsync(count.get(), 0, 8, compute.get()));
  wall.mark("workspace");

  Event up0(true), up1(true), k0(true), k1(true);
  up0.record(copy.get());
  if (!have) {
    Uploader uploader(res, frames, plane);
    uploader.upload(cube.get(), 0, plan.frameCount, copy.get());
    up1.record(copy.get());
    copy.sync();
    if (slot) {
      slot->key = job.cubeKey;
      ++slot->uploads;
    }
  } else {
    up1.record(copy.get());
    ++slot->reused;
  }
  poll();
  ST_CUDA_CHECK(cudaStreamWaitEvent(compute.get(), up1.get(), 0));

  TreeLevelLaunch lv{};
  lv.frames = cube.get();
  lv.frameIndex = ws.frameIndex.get();
  lv.width = plan.width;
  lv.height = plan.height;
  lv.jobs = ws.jobs.get();
  lv.segTab = ws.segTab.get();
  lv.rowTab = ws.rowTab.get();
  lv.shiftX = ws.shiftX.get();
  lv.shiftY = ws.shiftY.get();
  lv.directPlain = job.treeDirectPlain;
  TreeRootLaunch rt{};
  rt.in = arena[tree.cut & 1].get();
  rt.cutBase = ws.cutBase.get();
  rt.cutPitch = ws.cutPitch.get();
  rt.colBase = ws.colBase.get();
  rt.rowBase = ws.rowBase.get();
  rt.cut = tree.cut;
  rt.shape = job.treeRootShape;
  rt.width = plan.width;
  rt.height = plan.height;
  rt.tileRows = tree.tileRows;
  rt.nvx = plan.nvx;
  rt.nvy = plan.nvy;
  rt.spanX = reinterpret_cast<const int2*>(spanX.get());
  rt.spanY = reinterpret_cast<const int2*>(spanY.get());
  rt.maskX = plan.maskX.empty() ? nullptr : maskX.get();
  rt.maskY = plan.maskY.empty() ? nullptr : maskY.get();
  rt.maskWords = plan.maskWords;
  rt.invNorm = invNorm.get();
  rt.snrThreshold = plan.snrThreshold;
  rt.minFrames = plan.minFrames;
  rt.mapKeys = mapKeys.get();
  rt.cells = cells.get();
  rt.cellCount = count.get();
  rt.cellCapacity = job.cellCapacity;

  wall.mark("upload and set-up");
  loadTreeKernels();  // the module's loading is not kernel time (it stays in search()'s wall time)
  wall.mark("kernel module");
  std::vector<Event> marks;
  const bool profile = job.profile && tileBegin < tileEnd;
  if (profile) {
    for (std::size_t i = 0; i <= tree.levels.size() + 1; ++i)
      marks.emplace_back(true);
  }
  k0.record(compute.get());
  for (int t = tileBegin; t < tileEnd; ++t) {
    const int y0 = t * tree.tileRows;
    const bool timed = profile && t == tileBegin;
    if (timed) marks[0].record(compute.get());
    for (std::size_t l = 0; l < tree.levels.size(); ++l) {
      const TreeDeviceLevel& level = tree.levels[l];
      lv.y0 = y0;
      lv.rowJobs = ws.rowJobs.get() + level.rowBegin;
      lv.rows = level.rowEnd - level.rowBegin;
      lv.in = arena[level.arena ^ 1].get();
      lv.out = arena[level.arena].get();
      launchTreeLevel(lv, compute.get());
      if (timed) marks[l + 1].record(compute.get());
    }
    rt.y0 = y0;
    launchTreeRoot(rt, compute.get());
    if (timed) marks.back().record(compute.get());
    // Bounded queue: wait for the previous tile so cancellation is prompt.
    compute.sync();
    poll();
    progress(static_cast<double>(t - tileBegin + 1) / std::max(1, tileEnd - tileBegin));
  }
  k1.record(compute.get());
  compute.sync();
  wall.mark("kernels");

  DeviceOutcome out;
  out.kernelSeconds = elapsedSeconds(k0, k1);
  out.uploadSeconds = elapsedSeconds(up0, up1);
  out.mapKeys.resize(nv);
  ST_CUDA_CHECK(cudaMemcpy(out.mapKeys.data(), mapKeys.get(), nv * 8, cudaMemcpyDeviceToHost));
  unsigned long long n = 0;
  ST_CUDA_CHECK(cudaMemcpy(&n, count.get(), sizeof(n), cudaMemcpyDeviceToHost));
  out.cellsAbove = n;
  out.cells.resize(std::min<std::size_t>(n, job.cellCapacity));
  if (!out.cells.empty()) {
    ST_CUDA_CHECK(cudaMemcpy(out.cells.data(), cells.get(), out.cells.size() * sizeof(DeviceCell),
                             cudaMemcpyDeviceToHost));
  }
  wall.mark("read-back");
  std::string levels;
  if (profile) {
    levels = "; first tile, ms per level (depth):";
    for (std::size_t l = 0; l + 1 < marks.size(); ++l) {
      const std::string depth = l < tree.levels.size() ? std::to_string(tree.levels[l].depth) : "root";
      char buf[48];
      std::snprintf(buf, sizeof(buf), " %s %.2f", depth.c_str(),
                    1e3 * elapsedSeconds(marks[l], marks[l + 1]));
      levels += buf;
    }
  }
  out.note = "tree: cube resident (" + std::to_string(cubeFloats * 4 >> 20) + " MiB, " +
             (have ? std::string("already on the device: no upload")
                   : "upload " + std::to_string(static_cast<int>(out.uploadSeconds * 1e3)) + " ms") +
             "), tiles " + std::to_string(tileBegin) + ".." + std::to_string(tileEnd - 1) + " of " +
             std::to_string(tree.tileRows) + " rows, partial stacks " +
             std::to_string(tree.arenaBytes() >> 20) + " MiB, tables " +
             std::to_string(tree.tableBytes() >> 20) + " MiB (" +
             (kept              ? "kept from the last search"
              : job.treePlanKey ? "made, kept for the next"
                                : "made") +
             "), top " + std::to_string(tree.cut) + " levels in registers; wall: " + wall.str() + levels;
  return out;
}

}  // namespace st::gpu

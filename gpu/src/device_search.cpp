#include "device_search.hpp"

#include <algorithm>
#include <cstring>
#include <memory>

#include "cuda_check.hpp"
#include "uploader.hpp"
#include "wall_phases.hpp"
#include "st/common/parallel.hpp"

namespace st::gpu {
namespace {

constexpr std::size_t kReserveBytes = std::size_t{256} << 20;  // left free for the runtime and others
constexpr std::size_t kUploadChunkBytes = std::size_t{128} << 20;
constexpr int kVelocitiesPerLaunch = 2048;

template <class T>
DeviceBuffer<T> toDevice(const std::vector<T>& host) {
  DeviceBuffer<T> d(std::max<std::size_t>(host.size(), 1));
  if (!host.empty())
    ST_CUDA_CHECK(cudaMemcpy(d.get(), host.data(), host.size() * sizeof(T), cudaMemcpyHostToDevice));
  return d;
}

/// Everything one device holds for the whole search besides frames and partial sums.
struct DeviceTables {
  DeviceBuffer<int> shiftX, shiftY, spanX, spanY;
  DeviceBuffer<float> invNorm;
  DeviceBuffer<unsigned long long> mapKeys;
  DeviceBuffer<DeviceCell> cells;
  DeviceBuffer<unsigned long long> count;
};

std::size_t tableBytes(const HostPlan& plan, std::size_t cellCapacity) {
  return (plan.shiftX.size() + plan.shiftY.size() + plan.spanX.size() + plan.spanY.size()) * sizeof(int) +
         plan.invNorm.size() * sizeof(float) + static_cast<std::size_t>(plan.nvx) * plan.nvy * 8 +
         cellCapacity * sizeof(DeviceCell) + 64;
}

SearchLaunch baseLaunch(const HostPlan& plan, const DeviceTables& t, const DeviceJob& job) {
  SearchLaunch p{};
  p.width = plan.width;
  p.height = plan.height;
  p.frameCount = plan.frameCount;
  p.shiftX = t.shiftX.get();
  p.shiftY = t.shiftY.get();
  p.spanX = reinterpret_cast<const int2*>(t.spanX.get());
  p.spanY = reinterpret_cast<const int2*>(t.spanY.get());
  p.nvx = plan.nvx;
  p.nvy = plan.nvy;
  p.invNorm = t.invNorm.get();
  p.snrThreshold = plan.snrThreshold;
  p.minFrames = plan.minFrames;
  p.mapKeys = t.mapKeys.get();
  p.cells = t.cells.get();
  p.cellCount = t.count.get();
  p.cellCapacity = job.cellCapacity;
  p.vtileX = plan.vtileX;
  p.vtileY = plan.vtileY;
  p.pitch = plan.pitch;
  p.winRows = plan.winRows;
  p.framesPerStage = plan.framesPerStage;
  p.variant = plan.tiledMode;
  p.groups = plan.rowGroups;
  p.stairRows = plan.stairRows;
  p.stairTma = plan.stairTma;
  p.stairPipe = plan.stairPipe;
  return p;
}

std::string kernelName(const HostPlan& plan, bool naive) {
  if (naive) return ", naive kernel";
  if (plan.kernel == HostPlan::Kernel::Stair) {
    return ", stair kernel (" + std::to_string(kStairVx) + " x " + std::to_string(kStairVy) +
           " velocities per block, window " + std::to_string(plan.winRows) + " x " +
           std::to_string(plan.pitch) + ", " + std::to_string(plan.framesPerStage) + " frames per stage)";
  }
  if (plan.kernel == HostPlan::Kernel::Row) {
    return ", row kernel (" + std::to_string(plan.rowGroups * kRowVelocities) +
           " velocities per block, window " + std::to_string(plan.winRows) + " x " +
           std::to_string(plan.pitch) + ", " + std::to_string(plan.framesPerStage) + " frames per stage)";
  }
  return ", tiled kernel";
}

std::size_t offsetInts(const HostPlan& plan) {
  if (plan.kernel == HostPlan::Kernel::Stair) return stairOffsetInts();
  return plan.kernel == HostPlan::Kernel::Row ? rowOffsetInts() : static_cast<std::size_t>(kVelPerBlock + 2);
}

int tilesFor(const HostPlan& plan, int rows) {
  if (plan.kernel == HostPlan::Kernel::Stair) return stairTileCount(plan.nvx, rows);
  if (plan.kernel == HostPlan::Kernel::Row) return rowTileCount(plan.nvx, rows, plan.rowGroups);
  return ((plan.nvx + plan.vtileX - 1) / plan.vtileX) * ((rows + plan.vtileY - 1) / plan.vtileY);
}

/// Runs the search, timing each launch with events on the compute stream.
class Launcher {
 public:
  Launcher(const HostPlan& plan, bool naive, cudaStream_t stream, int maxRows)
      : m_plan(plan), m_naive(naive), m_stream(stream) {
    if (!naive) {
      const std::size_t n =
          static_cast<std::size_t>(tilesFor(plan, maxRows)) * plan.frameCount * offsetInts(plan);
      m_offsets = DeviceBuffer<int>(n);
      if (plan.kernel == HostPlan::Kernel::Stair) {
        configureStairKernel(stairSharedBytes(plan.framesPerStage, plan.stairRows), plan.stairRows);
      } else if (plan.kernel == HostPlan::Kernel::Row) {
        configureRowKernel(rowSharedBytes(plan.pitch, plan.winRows, plan.framesPerStage));
      } else {
        configureTiledKernel(tiledSharedBytes(plan.pitch, plan.winRows, plan.framesPerStage));
      }
    }
  }
  /// Prepares the window offsets of velocity rows [iy0, iy1).
  void prepare(SearchLaunch& p, int iy0, int iy1) {
    p.iy0 = iy0;
    p.iy1 = iy1;
    if (m_naive) return;
    p.tileOffsets = m_offsets.get();
    if (m_plan.kernel == HostPlan::Kernel::Stair) {
      launchStairOffsets(p, m_offsets.get(), tilesFor(m_plan, iy1 - iy0), m_stream);
    } else if (m_plan.kernel == HostPlan::Kernel::Row) {
      launchRowOffsets(p, m_offsets.get(), tilesFor(m_plan, iy1 - iy0), m_stream);
    } else {
      launchTileOffsets(p, m_offsets.get(), tilesFor(m_plan, iy1 - iy0), m_stream);
    }
  }
  void launch(const SearchLaunch& p) {
    m_timers.emplace_back(std::make_unique<Event>(true), std::make_unique<Event>(true));
    m_timers.back().first->record(m_stream);
    if (m_naive) {
      launchNaiveSearch(p, m_stream);
    } else if (m_plan.kernel == HostPlan::Kernel::Stair) {
      launchStairSearch(p, m_stream);
    } else if (m_plan.kernel == HostPlan::Kernel::Row) {
      launchRowSearch(p, m_stream);
    } else {
      launchTiledSearch(p, m_stream);
    }
    m_timers.back().second->record(m_stream);
  }
  /// Device seconds of all launches so far (synchronises).
  double seconds() const {
    double s = 0.0;
    for (const auto& [a, b] : m_timers) {
      b->sync();
      float ms = 0.0f;
      ST_CUDA_CHECK(cudaEventElapsedTime(&ms, a->get(), b->get()));
      s += ms * 1e-3;
    }
    return s;
  }

 private:
  const HostPlan& m_plan;
  bool m_naive;
  cudaStream_t m_stream;
  DeviceBuffer<int> m_offsets;
  std::vector<std::pair<std::unique_ptr<Event>, std::unique_ptr<Event>>> m_timers;
};

}  // namespace

DeviceOutcome runOnDevice(const HostPlan& plan, const float* frames, const DeviceJob& job,
                          const std::function<void(double)>& progress, const CancelToken& cancel,
                          const std::atomic<bool>& abort) {
  auto poll = [&] {
    cancel.throwIfCancelled();
    if (abort.load(std::memory_order_relaxed)) throw Cancelled();
  };
  WallPhases wall;
  ST_CUDA_CHECK(cudaSetDevice(job.device));
  std::unique_ptr<DeviceResources> own;
  DeviceResources& res = ensureResources(job.resources ? *job.resources : own);
  std::size_t freeBytes = 0;
  std::size_t totalBytes = 0;
  ST_CUDA_CHECK(cudaMemGetInfo(&freeBytes, &totalBytes));
  std::size_t budget = freeBytes > kReserveBytes ? freeBytes - kReserveBytes : 0;
  if (job.memoryLimitBytes > 0) budget = std::min(budget, job.memoryLimitBytes);

  const int n = plan.frameCount;
  const std::size_t plane = static_cast<std::size_t>(plan.width) * plan.height;
  const std::size_t frameBytes = plane * sizeof(float);
  const std::size_t cubeBytes = frameBytes * n;
  const int rows = job.iyEnd - job.iyBegin;
  // The naive kernel also serves when the shift spread of 8 velocities is too wide for shared memory.
  const bool naive = job.naiveKernel || plan.kernel == HostPlan::Kernel::Naive;
  const int step = naive ? 1 : plan.vtileY;
  int chunkRows = std::max(1, kVelocitiesPerLaunch / std::max(1, plan.nvx));
  chunkRows = std::min(rows, (chunkRows + step - 1) / step * step);
  auto offsetBytes = [&](int r) {
    return naive ? 0 : static_cast<std::size_t>(tilesFor(plan, r)) * n * offsetInts(plan) * sizeof(int);
  };
  auto partialBytes = [&](int r) { return static_cast<std::size_t>(r) * plan.nvx * frameBytes; };
  const std::size_t fixed = tableBytes(plan, job.cellCapacity);

  DeviceOutcome out;
  const bool resident = fixed + offsetBytes(chunkRows) + cubeBytes <= budget;
  int frameChunk = n;
  if (!resident) {
    if (naive)
      throw GpuError(
          "the naive kernel (used for very coarse velocity grids) needs the whole cube on the device");
    // Velocity rows per chunk: partial sums take at most half of what is left.
    const std::size_t room = budget > fixed ? budget - fixed : 0;
    // Partial sums take at most half of what is left, or, when one velocity row needs more, all but two
    // frames.
    const std::size_t perRow = partialBytes(1) + offsetBytes(1);
    std::size_t fit = room / 2 / perRow;
    if (fit < 1 && room > 2 * frameBytes) fit = (room - 2 * frameBytes) / perRow;
    chunkRows = std::min<int>(chunkRows, static_cast<int>(std::min<std::size_t>(fit, 1 << 20)));
    if (chunkRows < 1) {
      throw GpuError("not enough device memory: one velocity row of partial sums needs " +
                     std::to_string(partialBytes(1) >> 10) + " KiB, " + std::to_string(room >> 10) +
                     " KiB allowed");
    }
    const std::size_t left = room - partialBytes(chunkRows) - offsetBytes(chunkRows);
    frameChunk = static_cast<int>(std::min<std::size_t>(n, left / (2 * frameBytes)));
    if (frameChunk < 1) throw GpuError("not enough device memory for two frames and the partial sums");
  }

  DeviceTables t{toDevice(plan.shiftX),
                 toDevice(plan.shiftY),
                 toDevice(plan.spanX),
                 toDevice(plan.spanY),
                 toDevice(plan.invNorm),
                 DeviceBuffer<unsigned long long>(static_cast<std::size_t>(plan.nvx) * plan.nvy),
                 DeviceBuffer<DeviceCell>(std::max<std::size_t>(job.cellCapacity, 1)),
                 DeviceBuffer<unsigned long long>(1)};
  Stream& compute = res.compute;
  Stream& copy = res.copy;
  ST_CUDA_CHECK(cudaMemsetAsync(t.mapKeys.get(), 0, t.mapKeys.bytes(), compute.get()));
  ST_CUDA_CHECK(cudaMemsetAsync(t.count.get(), 0, sizeof(unsigned long long), compute.get()));
  SearchLaunch p = baseLaunch(plan, t, job);
  Launcher launcher(plan, naive, compute.get(), chunkRows);
  Uploader uploader(res, frames, plane);
  Event uploaded;
  wall.mark("set-up");
  int rowsDone = 0;
  auto report = [&](int r) {
    rowsDone += r;
    progress(static_cast<double>(rowsDone) / std::max(1, rows));
  };

  if (resident) {
    DeviceBuffer<float> cube(static_cast<std::size_t>(n) * plane);
    p.frames = cube.get();
    p.frameBase = 0;
    const int firstEnd = std::min(job.iyEnd, job.iyBegin + chunkRows);
    const int uploadFrames = std::max<int>(1, static_cast<int>(kUploadChunkBytes / frameBytes));
    // The first velocity chunk follows the upload frame chunk by frame chunk (partial sums on the device)
    // when memory allows; the others run over all frames in one launch.
    const bool overlap =
        !naive && uploadFrames < n &&
        fixed + offsetBytes(chunkRows) + cubeBytes + partialBytes(firstEnd - job.iyBegin) <= budget;
    DeviceBuffer<float> partial(overlap ? static_cast<std::size_t>(firstEnd - job.iyBegin) * plan.nvx * plane
                                        : 0);
    wall.mark("allocation");
    if (overlap) launcher.prepare(p, job.iyBegin, firstEnd);
    p.partial = partial.get();
    for (int n0 = 0; n0 < n; n0 += uploadFrames) {
      const int n1 = std::min(n, n0 + uploadFrames);
      uploader.upload(cube.get() + static_cast<std::size_t>(n0) * plane, n0, n1, copy.get());
      uploaded.record(copy.get());
      ST_CUDA_CHECK(cudaStreamWaitEvent(compute.get(), uploaded.get(), 0));
      if (overlap) {
        p.f0 = n0;
        p.f1 = n1;
        p.loadPartial = n0 > 0;
        p.finalize = n1 == n;
        launcher.launch(p);
      }
      poll();
    }
    wall.mark("upload enqueued");
    p.partial = nullptr;
    p.loadPartial = false;
    p.finalize = true;
    p.f0 = 0;
    p.f1 = n;
    int iy = job.iyBegin;
    if (overlap) {
      compute.sync();
      wall.mark("first chunk");
      report(firstEnd - iy);
      iy = firstEnd;
    }
    for (; iy < job.iyEnd; iy += chunkRows) {
      const int iy1 = std::min(job.iyEnd, iy + chunkRows);
      launcher.prepare(p, iy, iy1);
      launcher.launch(p);
      compute.sync();
      poll();
      report(iy1 - iy);
    }
    wall.mark("other chunks");
    out.note = "cube resident (" + std::to_string(cubeBytes >> 20) + " MiB), " +
               (overlap ? "upload overlapped with the first velocity chunk" : "upload then search") +
               kernelName(plan, naive);
  } else {
    DeviceBuffer<float> buf[2] = {DeviceBuffer<float>(static_cast<std::size_t>(frameChunk) * plane),
                                  DeviceBuffer<float>(static_cast<std::size_t>(frameChunk) * plane)};
    DeviceBuffer<float> partial(partialBytes(chunkRows) / sizeof(float));
    Event done[2];
    p.partial = partial.get();
    for (int iy = job.iyBegin; iy < job.iyEnd; iy += chunkRows) {
      const int iy1 = std::min(job.iyEnd, iy + chunkRows);
      launcher.prepare(p, iy, iy1);
      for (int n0 = 0, c = 0; n0 < n; n0 += frameChunk, ++c) {
        const int n1 = std::min(n, n0 + frameChunk);
        ST_CUDA_CHECK(cudaStreamWaitEvent(copy.get(), done[c & 1].get(), 0));
        uploader.upload(buf[c & 1].get(), n0, n1, copy.get());
        uploaded.record(copy.get());
        ST_CUDA_CHECK(cudaStreamWaitEvent(compute.get(), uploaded.get(), 0));
        p.frames = buf[c & 1].get();
        p.frameBase = n0;
        p.f0 = n0;
        p.f1 = n1;
        p.loadPartial = n0 > 0;
        p.finalize = n1 == n;
        launcher.launch(p);
        done[c & 1].record(compute.get());
        poll();
      }
      compute.sync();
      report(iy1 - iy);
    }
    out.note = "cube of " + std::to_string(cubeBytes >> 20) + " MiB does not fit in " +
               std::to_string(budget >> 20) + " MiB: frames streamed in chunks of " +
               std::to_string(frameChunk) + ", velocities in chunks of " + std::to_string(chunkRows) +
               " rows" + kernelName(plan, naive);
  }
  wall.mark("free");
  compute.sync();
  copy.sync();
  out.kernelSeconds = launcher.seconds();
  const std::size_t mapOffset = static_cast<std::size_t>(job.iyBegin) * plan.nvx;
  out.mapKeys.resize(static_cast<std::size_t>(rows) * plan.nvx);
  ST_CUDA_CHECK(cudaMemcpy(out.mapKeys.data(), t.mapKeys.get() + mapOffset, out.mapKeys.size() * 8,
                           cudaMemcpyDeviceToHost));
  unsigned long long count = 0;
  ST_CUDA_CHECK(cudaMemcpy(&count, t.count.get(), sizeof(count), cudaMemcpyDeviceToHost));
  out.cellsAbove = count;
  out.cells.resize(std::min<std::size_t>(count, job.cellCapacity));
  if (!out.cells.empty()) {
    ST_CUDA_CHECK(cudaMemcpy(out.cells.data(), t.cells.get(), out.cells.size() * sizeof(DeviceCell),
                             cudaMemcpyDeviceToHost));
  }
  wall.mark("read-back");
  out.note += "; wall: " + wall.str();
  return out;
}

}  // namespace st::gpu

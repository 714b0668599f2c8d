#include "device_search.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>
#include <mutex>

#include "cuda_check.hpp"
#include "resident_cube.hpp"
#include "uploader.hpp"
#include "wall_phases.hpp"
#include "st/common/parallel.hpp"

namespace st::gpu {
namespace {

constexpr std::size_t kReserveBytes = std::size_t{256} << 20;  // left free for the runtime and others
/// Resident cube: frames per upload step, each followed by a launch of the first velocity rows over them
/// with partial sums. 256 MiB: the partial sums' traffic cost 9 ms less of kernels than with 128 MiB steps
/// on the paper's problem (H100, 2026-11-22: 0.366 s vs 0.375 s).
constexpr std::size_t kUploadChunkBytes = std::size_t{256} << 20;
constexpr int kVelocitiesPerLaunch = 2048;
/// Host-to-device upload through the staging buffers, for sizing the first velocity rows so that their
/// kernels last as long as the upload: 30-37 GB/s typical, 17.6 GB/s the slowest measured for the paper's
/// cube (H100 host, 2026-11-22). Rows sized for 16 GB/s (28 instead of 20) cost 15 ms more of partial sums
/// and gained nothing on a typical upload.
constexpr double kSlowUploadBytesPerS = 25e9;

/// Everything one device holds for the whole search besides frames and partial sums.
struct DeviceTables {
  DeviceBuffer<int> shiftX, shiftY, spanX, spanY;
  DeviceBuffer<unsigned> maskX, maskY;  ///< registered frames only (1 word each otherwise, unused)
  DeviceBuffer<float> invNorm;
  DeviceBuffer<unsigned long long> mapKeys;
  DeviceBuffer<DeviceCell> cells;
  DeviceBuffer<unsigned long long> count;
};

std::size_t tableBytes(const HostPlan& plan, std::size_t cellCapacity) {
  return (plan.shiftX.size() + plan.shiftY.size() + plan.spanX.size() + plan.spanY.size() +
          plan.maskX.size() + plan.maskY.size()) *
             sizeof(int) +
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
  p.maskX = plan.maskX.empty() ? nullptr : t.maskX.get();
  p.maskY = plan.maskY.empty() ? nullptr : t.maskY.get();
  p.maskWords = plan.maskWords;
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
  p.framesHalf = nullptr;  // JobRun::runResident sets it when the half copy fits
  p.halfInvScale = 1.0f / plan.halfScale;
  return p;
}

std::string kernelName(const HostPlan& plan, bool naive, bool half) {
  if (naive) return ", naive kernel";
  if (plan.kernel == HostPlan::Kernel::Stair && half) {
    return ", stair kernel (" + std::to_string(kStairVx) + " x " + std::to_string(kStairVy) +
           " velocities per block, Float16 frames: window " + std::to_string(plan.winRows) + " x " +
           std::to_string(kStairHalfPitch) + " pairs, " + std::to_string(plan.halfFramesPerStage) +
           " frames per stage summed in half)";
  }
  if (plan.kernel == HostPlan::Kernel::Stair) {
    return ", stair kernel (" + std::to_string(kStairVx) + " x " + std::to_string(kStairVy) +
           " velocities per block, window " + std::to_string(plan.winRows) + " x " +
           std::to_string(plan.pitch) + ", " + std::to_string(plan.framesPerStage) + " frames per stage" +
           (plan.halfFrames ? "; Float16 asked, float frames: the half copy does not fit or the cube is "
                              "streamed)"
                            : ")");
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
        configureStairKernel(std::max(stairSharedBytes(plan.framesPerStage, plan.stairRows),
                                      plan.halfFrames ? stairHalfSharedBytes(plan.halfFramesPerStage) : 0),
                             plan.stairRows);
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
  /// Launches `work` on the compute stream timed like a search launch (Float16 conversions: counted in the
  /// kernel time).
  template <class Work>
  void timed(Work work) {
    m_timers.emplace_back(std::make_unique<Event>(true), std::make_unique<Event>(true));
    m_timers.back().first->record(m_stream);
    work();
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

/// How one job uses the device's memory: the cube resident (velocity rows in chunks) or streamed in frame
/// chunks with partial sums per velocity chunk.
struct MemoryLayout {
  bool naive = false;
  bool resident = true;
  bool half = false;          ///< resident, Float16 asked: the half copy of the cube fits beside it
  std::size_t halfBytes = 0;  ///< the half copy's bytes
  int chunkRows = 1;          ///< velocity rows per launch
  int firstRows = 0;   ///< resident: velocity rows summed chunk by chunk while the cube uploads (0: none)
  int frameChunk = 0;  ///< frames per upload when streamed (the whole cube when resident)
  std::size_t budget = 0;
  std::size_t fixedBytes = 0;  ///< tables, map, cells
  std::size_t frameBytes = 0;
  std::size_t uploadChunkBytes = kUploadChunkBytes;  ///< resident: frames per upload step
  std::function<std::size_t(int)> offsetBytes;       ///< window offsets of r velocity rows
  std::function<std::size_t(int)> partialBytes;      ///< partial sums of r velocity rows
};

/// Velocity rows to sum while the cube uploads (frame chunk by frame chunk, partial sums on the device):
/// enough to keep the device busy through an upload at kSlowUploadBytesPerS, at least one launch's worth,
/// within the memory allowed; 0 = no overlap (the naive kernel, a cube of one upload chunk, no memory).
int overlapRows(const HostPlan& plan, const MemoryLayout& m, int rows, int step) {
  const int n = plan.frameCount;
  const std::size_t cubeBytes = m.frameBytes * n;
  if (m.naive || m.uploadChunkBytes >= cubeBytes) return 0;
  // Additions per second of the kernels (H100, 2026-11-22: stair 1.05e13, tiled and row ~2.8e12).
  const double rate = plan.kernel == HostPlan::Kernel::Stair ? 1.0e13 : 2.8e12;
  const double rowSeconds = static_cast<double>(n) * (m.frameBytes / sizeof(float)) * plan.nvx / rate;
  const double uploadSeconds = static_cast<double>(cubeBytes) / kSlowUploadBytesPerS;
  int r = static_cast<int>(std::ceil(uploadSeconds / rowSeconds));
  r = std::min(rows, std::max(m.chunkRows, (r + step - 1) / step * step));
  auto fits = [&](int k) {
    return m.fixedBytes + m.offsetBytes(std::max(k, m.chunkRows)) + cubeBytes + (m.half ? m.halfBytes : 0) +
               m.partialBytes(k) <=
           m.budget;
  };
  while (r > 0 && !fits(r))
    r = r > step ? r - step : 0;
  return r;
}

/// The layout for `job` within the memory the device has free (less a reserve) or the job allows. Throws
/// st::GpuError naming the sizes when not even one velocity row of partial sums and two frames fit.
MemoryLayout planMemory(const HostPlan& plan, const DeviceJob& job, std::size_t residentBytes) {
  std::size_t freeBytes = 0;
  std::size_t totalBytes = 0;
  ST_CUDA_CHECK(cudaMemGetInfo(&freeBytes, &totalBytes));
  MemoryLayout m;
  freeBytes += residentBytes;  // the cube already on the device is counted below as the cube's bytes
  m.budget = freeBytes > kReserveBytes ? freeBytes - kReserveBytes : 0;
  if (job.memoryLimitBytes > 0) m.budget = std::min(m.budget, job.memoryLimitBytes);
  const int n = plan.frameCount;
  m.frameBytes = static_cast<std::size_t>(plan.width) * plan.height * sizeof(float);
  if (job.uploadChunkBytes > 0) m.uploadChunkBytes = job.uploadChunkBytes;
  const std::size_t cubeBytes = m.frameBytes * n;
  const int rows = job.iyEnd - job.iyBegin;
  // The naive kernel also serves when the shift spread of 8 velocities is too wide for shared memory.
  m.naive = job.naiveKernel || plan.kernel == HostPlan::Kernel::Naive;
  const int step = m.naive ? 1 : plan.vtileY;
  m.chunkRows = std::max(1, kVelocitiesPerLaunch / std::max(1, plan.nvx));
  m.chunkRows = std::min(rows, (m.chunkRows + step - 1) / step * step);
  const bool naive = m.naive;
  m.offsetBytes = [&plan, n, naive](int r) {
    return naive ? 0 : static_cast<std::size_t>(tilesFor(plan, r)) * n * offsetInts(plan) * sizeof(int);
  };
  m.partialBytes = [fb = m.frameBytes, nvx = plan.nvx](int r) {
    return static_cast<std::size_t>(r) * nvx * fb;
  };
  m.fixedBytes = tableBytes(plan, job.cellCapacity);
  m.resident = m.fixedBytes + m.offsetBytes(m.chunkRows) + cubeBytes <= m.budget;
  m.frameChunk = n;
  m.halfBytes = static_cast<std::size_t>(n) * (plan.width + kStairHalfPad) * plan.height * 4;
  m.half = m.resident && plan.halfFrames && !m.naive &&
           m.fixedBytes + m.offsetBytes(m.chunkRows) + cubeBytes + m.halfBytes <= m.budget;
  if (m.resident) {
    m.firstRows = residentBytes > 0 ? 0 : overlapRows(plan, m, rows, step);
    return m;
  }
  if (m.naive) {
    throw GpuError(
        "the naive kernel (used for very coarse velocity grids) needs the whole cube on the device");
  }
  // Partial sums take at most half of what is left, or, when one velocity row needs more, all but two
  // frames.
  const std::size_t room = m.budget > m.fixedBytes ? m.budget - m.fixedBytes : 0;
  const std::size_t perRow = m.partialBytes(1) + m.offsetBytes(1);
  std::size_t fit = room / 2 / perRow;
  if (fit < 1 && room > 2 * m.frameBytes) fit = (room - 2 * m.frameBytes) / perRow;
  m.chunkRows = std::min<int>(m.chunkRows, static_cast<int>(std::min<std::size_t>(fit, 1 << 20)));
  if (m.chunkRows < 1) {
    throw GpuError("not enough device memory: one velocity row of partial sums needs " +
                   std::to_string(m.partialBytes(1) >> 10) + " KiB, " + std::to_string(room >> 10) +
                   " KiB allowed");
  }
  const std::size_t left = room - m.partialBytes(m.chunkRows) - m.offsetBytes(m.chunkRows);
  m.frameChunk = static_cast<int>(std::min<std::size_t>(n, left / (2 * m.frameBytes)));
  if (m.frameChunk < 1) throw GpuError("not enough device memory for two frames and the partial sums");
  return m;
}

DeviceTables makeTables(const HostPlan& plan, std::size_t cellCapacity) {
  return DeviceTables{toDevice(plan.shiftX),
                      toDevice(plan.shiftY),
                      toDevice(plan.spanX),
                      toDevice(plan.spanY),
                      toDevice(plan.maskX),
                      toDevice(plan.maskY),
                      toDevice(plan.invNorm),
                      DeviceBuffer<unsigned long long>(static_cast<std::size_t>(plan.nvx) * plan.nvy),
                      DeviceBuffer<DeviceCell>(std::max<std::size_t>(cellCapacity, 1)),
                      DeviceBuffer<unsigned long long>(1)};
}

/// One runOnDevice call: tables, launcher and uploader on the device's streams, then the resident or the
/// streamed loop, then the read-back of the map and the cells.
class JobRun {
 public:
  JobRun(const HostPlan& plan, const float* frames, const DeviceJob& job, DeviceResources& res,
         const MemoryLayout& m, const std::function<void(double)>& progress, std::function<void()> poll)
      : m_plan(plan),
        m_job(job),
        m_m(m),
        m_res(res),
        m_progress(progress),
        m_poll(std::move(poll)),
        m_t(makeTables(plan, job.cellCapacity)),
        m_p(baseLaunch(plan, m_t, job)),
        m_launcher(plan, m.naive, res.compute.get(), std::max(m.chunkRows, m.firstRows)),
        m_uploader(res, frames, plane()) {
    ST_CUDA_CHECK(cudaMemsetAsync(m_t.mapKeys.get(), 0, m_t.mapKeys.bytes(), compute()));
    ST_CUDA_CHECK(cudaMemsetAsync(m_t.count.get(), 0, sizeof(unsigned long long), compute()));
  }

  /// The device's resident cube: `have` = it holds this job's cube already (no upload).
  void useResident(ResidentSlot* slot, bool have) {
    m_slot = slot;
    m_have = have;
  }

  DeviceOutcome run(WallPhases& wall) {
    wall.mark("set-up");
    DeviceOutcome out;
    out.note = m_m.resident ? runResident(wall) : runStreamed();
    wall.mark(m_m.resident ? "free" : "streamed chunks");
    m_res.compute.sync();
    m_res.copy.sync();
    out.kernelSeconds = m_launcher.seconds();
    readBack(out);
    wall.mark("read-back");
    out.note += kernelName(m_plan, m_m.naive, m_m.half) + "; wall: " + wall.str();
    return out;
  }

 private:
  std::size_t plane() const { return static_cast<std::size_t>(m_plan.width) * m_plan.height; }
  cudaStream_t compute() const { return m_res.compute.get(); }
  cudaStream_t copy() const { return m_res.copy.get(); }
  void report(int rows) {
    m_rowsDone += rows;
    m_progress(static_cast<double>(m_rowsDone) / std::max(1, m_job.iyEnd - m_job.iyBegin));
  }
  /// Uploads frames [n0, n1) into `dst` and makes the compute stream wait for them.
  void upload(float* dst, int n0, int n1) {
    m_uploader.upload(dst, n0, n1, copy());
    m_uploaded.record(copy());
    ST_CUDA_CHECK(cudaStreamWaitEvent(compute(), m_uploaded.get(), 0));
  }
  /// Launches frames [f0, f1) of the prepared velocity rows, adding to the partial sums unless f0 is 0.
  void launchFrames(int f0, int f1) {
    m_p.f0 = f0;
    m_p.f1 = f1;
    m_p.loadPartial = f0 > 0;
    m_p.finalize = f1 == m_plan.frameCount;
    m_launcher.launch(m_p);
  }

  std::size_t halfWords() const {
    return static_cast<std::size_t>(m_plan.frameCount) * (m_plan.width + kStairHalfPad) * m_plan.height;
  }
  void toHalf(const float* cube, unsigned* half, int n0, int n1) {
    m_launcher.timed([&] {
      launchHalfPairs(cube, half, m_plan.width, m_plan.height, n0, n1, m_plan.halfScale, compute());
    });
  }

  /// The cube uploaded once; the first velocity chunk follows the upload frame chunk by frame chunk
  /// (partial sums on the device) when memory allows; the other chunks run over all frames in one launch.
  std::string runResident(WallPhases& wall) {
    const int n = m_plan.frameCount;
    const std::size_t cubeBytes = m_m.frameBytes * n;
    DeviceBuffer<float> own;
    if (m_have) {
      m_p.frames = m_slot->cube.get();
    } else {
      (m_slot ? m_slot->cube : own) = DeviceBuffer<float>(static_cast<std::size_t>(n) * plane());
      m_p.frames = (m_slot ? m_slot->cube : own).get();
    }
    float* cube = const_cast<float*>(m_p.frames);
    m_p.frameBase = 0;
    // Float16: the half pairs of each frame chunk made on the compute stream once it has arrived.
    DeviceBuffer<unsigned> half(m_m.half ? halfWords() : 0);
    if (m_m.half) {
      m_p.framesHalf = half.get();
      m_p.framesPerStage = m_plan.halfFramesPerStage;
      if (m_have) toHalf(cube, half.get(), 0, n);
    }
    const int firstEnd = m_job.iyBegin + m_m.firstRows;
    const int uploadFrames = std::max<int>(1, static_cast<int>(m_m.uploadChunkBytes / m_m.frameBytes));
    const bool overlap = m_m.firstRows > 0;
    DeviceBuffer<float> partial(m_m.partialBytes(m_m.firstRows) / sizeof(float));
    wall.mark("allocation");
    if (overlap) m_launcher.prepare(m_p, m_job.iyBegin, firstEnd);
    m_p.partial = partial.get();
    for (int n0 = 0; n0 < n && !m_have; n0 += uploadFrames) {
      const int n1 = std::min(n, n0 + uploadFrames);
      upload(cube + static_cast<std::size_t>(n0) * plane(), n0, n1);
      if (m_m.half) toHalf(cube, half.get(), n0, n1);
      if (overlap) launchFrames(n0, n1);
      m_poll();
    }
    wall.mark("upload enqueued");
    m_p.partial = nullptr;
    int iy = m_job.iyBegin;
    if (overlap) {
      m_res.compute.sync();
      wall.mark("first chunk");
      report(firstEnd - iy);
      iy = firstEnd;
    }
    for (; iy < m_job.iyEnd; iy += m_m.chunkRows) {
      const int iy1 = std::min(m_job.iyEnd, iy + m_m.chunkRows);
      m_launcher.prepare(m_p, iy, iy1);
      launchFrames(0, n);
      m_res.compute.sync();
      m_poll();
      report(iy1 - iy);
    }
    wall.mark("other chunks");
    if (m_slot && !m_have) {
      m_res.copy.sync();
      m_slot->key = m_job.cubeKey;  // uploaded whole: kept for the next search and stackAt
      ++m_slot->uploads;
    } else if (m_have) {
      ++m_slot->reused;
    }
    if (m_have)
      return "cube resident (" + std::to_string(cubeBytes >> 20) + " MiB), already on the device: no upload";
    return "cube resident (" + std::to_string(cubeBytes >> 20) + " MiB" + (m_slot ? ", kept" : "") + "), " +
           (overlap ? "upload overlapped with the first " + std::to_string(m_m.firstRows) + " velocity rows"
                    : std::string("upload then search"));
  }

  /// Frames streamed in chunks through two device buffers, once per velocity chunk, with partial sums.
  std::string runStreamed() {
    const int n = m_plan.frameCount;
    const std::size_t chunkFloats = static_cast<std::size_t>(m_m.frameChunk) * plane();
    DeviceBuffer<float> buf[2] = {DeviceBuffer<float>(chunkFloats), DeviceBuffer<float>(chunkFloats)};
    DeviceBuffer<float> partial(m_m.partialBytes(m_m.chunkRows) / sizeof(float));
    Event done[2];
    m_p.partial = partial.get();
    for (int iy = m_job.iyBegin; iy < m_job.iyEnd; iy += m_m.chunkRows) {
      const int iy1 = std::min(m_job.iyEnd, iy + m_m.chunkRows);
      m_launcher.prepare(m_p, iy, iy1);
      for (int n0 = 0, c = 0; n0 < n; n0 += m_m.frameChunk, ++c) {
        const int n1 = std::min(n, n0 + m_m.frameChunk);
        ST_CUDA_CHECK(cudaStreamWaitEvent(copy(), done[c & 1].get(), 0));
        upload(buf[c & 1].get(), n0, n1);
        m_p.frames = buf[c & 1].get();
        m_p.frameBase = n0;
        launchFrames(n0, n1);
        done[c & 1].record(compute());
        m_poll();
      }
      m_res.compute.sync();
      report(iy1 - iy);
    }
    return "cube of " + std::to_string((m_m.frameBytes * n) >> 20) + " MiB does not fit in " +
           std::to_string(m_m.budget >> 20) + " MiB: frames streamed in chunks of " +
           std::to_string(m_m.frameChunk) + ", velocities in chunks of " + std::to_string(m_m.chunkRows) +
           " rows";
  }

  void readBack(DeviceOutcome& out) const {
    const std::size_t mapOffset = static_cast<std::size_t>(m_job.iyBegin) * m_plan.nvx;
    out.mapKeys.resize(static_cast<std::size_t>(m_job.iyEnd - m_job.iyBegin) * m_plan.nvx);
    ST_CUDA_CHECK(cudaMemcpy(out.mapKeys.data(), m_t.mapKeys.get() + mapOffset, out.mapKeys.size() * 8,
                             cudaMemcpyDeviceToHost));
    unsigned long long count = 0;
    ST_CUDA_CHECK(cudaMemcpy(&count, m_t.count.get(), sizeof(count), cudaMemcpyDeviceToHost));
    out.cellsAbove = count;
    out.cells.resize(std::min<std::size_t>(count, m_job.cellCapacity));
    if (!out.cells.empty()) {
      ST_CUDA_CHECK(cudaMemcpy(out.cells.data(), m_t.cells.get(), out.cells.size() * sizeof(DeviceCell),
                               cudaMemcpyDeviceToHost));
    }
  }

  const HostPlan& m_plan;
  const DeviceJob& m_job;
  const MemoryLayout& m_m;
  DeviceResources& m_res;
  const std::function<void(double)>& m_progress;
  std::function<void()> m_poll;
  DeviceTables m_t;
  SearchLaunch m_p;
  Launcher m_launcher;
  Uploader m_uploader;
  Event m_uploaded;
  int m_rowsDone = 0;
  ResidentSlot* m_slot = nullptr;
  bool m_have = false;
};

}  // namespace

DeviceOutcome runOnDevice(const HostPlan& plan, const float* frames, const DeviceJob& job,
                          const std::function<void(double)>& progress, const CancelToken& cancel,
                          const std::atomic<bool>& abort) {
  WallPhases wall;
  ST_CUDA_CHECK(cudaSetDevice(job.device));
  std::unique_ptr<DeviceResources> own;
  DeviceResources& res = ensureResources(job.resources ? *job.resources : own);
  const std::size_t cubeFloats = static_cast<std::size_t>(plan.width) * plan.height * plan.frameCount;
  ResidentSlot* slot = job.cubeKey != 0 ? &residentSlot(job.device) : nullptr;
  std::unique_lock<std::mutex> lock;
  if (slot) lock = std::unique_lock<std::mutex>(slot->mutex);
  const bool have = slot && slot->holds(job.cubeKey, cubeFloats);
  if (slot && !have) slot->clear();
  const MemoryLayout layout = planMemory(plan, job, have ? slot->cube.bytes() : 0);
  if (!layout.resident && have) slot->clear();  // streamed: the frames go through chunk buffers
  JobRun run(plan, frames, job, res, layout, progress, [&] {
    cancel.throwIfCancelled();
    if (abort.load(std::memory_order_relaxed)) throw Cancelled();
  });
  run.useResident(layout.resident ? slot : nullptr, have && layout.resident);
  return run.run(wall);
}

}  // namespace st::gpu

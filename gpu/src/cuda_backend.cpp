// CudaBackend: the SearchBackend over every usable device. Threading rules: search() runs one host thread
// per device (each calls cudaSetDevice first and touches only its own device's memory); exceptions are
// caught in each thread and rethrown here; progress is reported from the device threads (ProgressSink is
// thread-safe by contract). stackAt runs on the first device, in the calling thread.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <exception>
#include <mutex>
#include <thread>

#include "cuda_bench_options.hpp"
#include "device_info.hpp"
#include "device_search.hpp"
#include "resident_cube.hpp"
#include "search_plan.hpp"
#include "st/common/error.hpp"
#include "st/common/fnv1a.hpp"
#include "st/gpu/cuda_backend.hpp"
#include "st/search/candidates.hpp"
#include "st/search/search_run.hpp"
#include "st/stack/csa.hpp"
#include "stack_engine.hpp"
#include "st/search/tree_plan.hpp"
#include "tree_search_device.hpp"
#include "uploader.hpp"
#include "wall_phases.hpp"
#include "cuda_check.hpp"
#include <functional>
#include <memory>

namespace st::gpu {
namespace {

class CudaBackend final : public CudaSearchBackend {
 public:
  CudaBackend(std::vector<DeviceInfo> devices, CudaOptions options, CudaBenchOptions bench)
      : m_devices(std::move(devices)),
        m_options(options),
        m_bench(bench),
        m_stack(m_devices.front().ordinal) {
    if (m_options.maxDevices > 0 && static_cast<int>(m_devices.size()) > m_options.maxDevices) {
      m_devices.resize(static_cast<std::size_t>(m_options.maxDevices));
    }
    m_resources.resize(m_devices.size());
    m_tree.resize(m_devices.size());
    for (const auto& d : m_devices)
      m_ordinals.push_back(d.ordinal);
  }

  [[nodiscard]] std::string name() const override {
    std::string out = "cuda: ";
    if (m_devices.size() > 1) out += std::to_string(m_devices.size()) + " x ";
    return out + m_devices.front().name;
  }
  [[nodiscard]] std::string lastNote() const override { return m_note; }
  [[nodiscard]] double lastKernelSeconds() const override { return m_kernelSeconds; }
  [[nodiscard]] double lastUploadSeconds() const override { return m_uploadSeconds; }
  [[nodiscard]] double lastTreeAdditions() const override { return m_treeAdditions; }

  search::SearchResult search(const search::FilteredCube& cube, const search::VelocityGrid& grid,
                              const search::SearchParams& params, ProgressSink& progress,
                              CancelToken& cancel) override {
    const auto start = std::chrono::steady_clock::now();
    search::validateSearchInput(cube, grid, params);
    validateForGpu(cube);
    m_cubeKey = m_options.keepCubeResident ? residentKey(cube.frames, cube.revision) : 0;
    // Another cube's resident copy is freed (its memory is this search's); a backend that keeps nothing
    // leaves the slots alone.
    if (m_options.keepCubeResident)
      releaseOtherCubes(m_ordinals.data(), static_cast<int>(m_ordinals.size()), m_cubeKey);
    if (params.method == search::SearchMethod::Tree)
      return searchTree(cube, grid, params, progress, cancel, start);
    releaseTreeWorkspaces();  // their memory is the exact search's
    if (params.method != search::SearchMethod::Exact) {
      throw InputError("search method '" + std::string(params.method.name()) + "' (expected exact or tree)");
    }
    search::SearchResult result =
        search::startSearchResult(cube, grid, params, name(), search::SearchMethod::Exact);
    WallPhases wall;
    HostPlan plan = makeHostPlan(cube, grid, result.snrThreshold, result.minFrames);
    applyKernelChoice(plan);
    std::size_t capacity = initialCapacity(params);
    progress.report(0.0, "velocity search (" + name() + ")");
    wall.mark("plan");
    std::vector<DeviceOutcome> outcomes = runAll(plan, cube, capacity, progress, cancel);
    wall.mark("devices");
    std::uint64_t above = 0;
    for (const auto& o : outcomes)
      above += o.cellsAbove;
    if (above > capacity) {
      // More cells passed than the buffer held: run again with room for all (never a silent truncation).
      capacity = checkedCapacity(above, result.snrThreshold);
      outcomes = runAll(plan, cube, capacity, progress, cancel);
    }
    mergeMap(outcomes, plan, result);
    result.cellsAboveThreshold = static_cast<std::int64_t>(above);
    search::setCandidates(result, collectCells(outcomes), cube, params);
    wall.mark("candidates");
    m_note = "host: " + wall.str() + "\n";
    m_kernelSeconds = 0.0;
    for (std::size_t i = 0; i < outcomes.size(); ++i) {
      m_note += "device " + std::to_string(m_devices[i].ordinal) + ": " + outcomes[i].note + "\n";
      m_kernelSeconds += outcomes[i].kernelSeconds;
    }
    result.backendNote = trimmed(m_note);
    result.elapsedS = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    progress.report(1.0, "velocity search (" + name() + ")");
    return result;
  }

  /// The tree search (tree_device_plan.hpp): tiles of rows spread over the devices, each holding the cube.
  search::SearchResult searchTree(const search::FilteredCube& cube, const search::VelocityGrid& grid,
                                  const search::SearchParams& params, ProgressSink& progress,
                                  CancelToken& cancel, std::chrono::steady_clock::time_point start) {
    search::SearchResult result =
        search::startSearchResult(cube, grid, params, name(), search::SearchMethod::Tree);
    WallPhases wall;
    const HostPlan plan = makeHostPlan(cube, grid, result.snrThreshold, result.minFrames);
    wall.mark("plan");
    std::size_t capacity = initialCapacity(params);
    const int cut = m_options.treeCut > 0 ? m_options.treeCut : kTreeDefaultCut;
    // The tree's plan and each device's workspace are kept between searches of the same resident cube and
    // grid (a re-search after a threshold change makes neither again); anything else frees them first.
    const std::uint64_t key = treePlanKey(cube, grid, cut);
    if (key == 0 || key != m_treeKey || !m_treePlan) {
      releaseTreeWorkspaces();
      const std::shared_ptr<const search::TreePlan> shared =
          search::sharedTreePlan(cube.frames.timeOffsetsS(), grid, cube.frames.frameOffsets());
      const search::TreePlan& tree = *shared;
      m_treePlan = std::make_shared<const TreeDevicePlan>(chooseTreeTiles(tree, plan, cube, capacity, cut));
      m_treeKey = key;
      wall.mark("tree plan");
    } else {
      wall.mark("tree plan kept");
    }
    const TreeDevicePlan& dplan = *m_treePlan;
    progress.report(0.0, "velocity search, tree (" + name() + ")");
    auto runTiles = [&](std::size_t cap) {
      return runOnDevices(std::min<int>(static_cast<int>(m_devices.size()), dplan.tiles), progress,
                          "velocity search, tree (" + name() + ")", [&](int d, int used, auto report) {
                            DeviceJob job;
                            job.device = m_devices[d].ordinal;
                            job.resources = &m_resources[static_cast<std::size_t>(d)];
                            job.cellCapacity = cap;
                            job.profile = m_bench.profileTree;
                            job.treeRootShape = m_bench.treeRootShape;
                            job.treeDirectPlain = m_bench.treeDirectPlain;
                            job.cubeKey = m_cubeKey;
                            job.treeWorkspace = &m_tree[static_cast<std::size_t>(d)];
                            job.treePlanKey = key;
                            const int t0 = static_cast<int>(static_cast<long>(dplan.tiles) * d / used);
                            const int t1 = static_cast<int>(static_cast<long>(dplan.tiles) * (d + 1) / used);
                            return runTreeOnDevice(dplan, plan, cube.frames.pixels().data(), job, t0, t1,
                                                   report, cancel, m_abort);
                          });
    };
    std::vector<DeviceOutcome> outcomes = runTiles(capacity);
    wall.mark("devices");
    std::uint64_t above = 0;
    for (const auto& o : outcomes)
      above += o.cellsAbove;
    if (above > capacity) {
      capacity = checkedCapacity(above, result.snrThreshold);
      outcomes = runTiles(capacity);
    }
    // Every device covers the whole grid (its own rows of pixels): the map is the maximum over devices.
    std::vector<unsigned long long> keys(grid.count(), 0ull);
    for (const auto& o : outcomes) {
      for (std::size_t i = 0; i < keys.size(); ++i)
        keys[i] = std::max(keys[i], o.mapKeys[i]);
    }
    DeviceOutcome merged;
    merged.mapKeys = std::move(keys);
    mergeMap({merged}, plan, result);
    result.cellsAboveThreshold = static_cast<std::int64_t>(above);
    search::setCandidates(result, collectCells(outcomes), cube, params);
    wall.mark("candidates");
    m_note = "host: " + wall.str() + "\n";
    m_kernelSeconds = 0.0;
    m_uploadSeconds = 0.0;
    for (std::size_t i = 0; i < outcomes.size(); ++i) {
      m_note += "device " + std::to_string(m_devices[i].ordinal) + ": " + outcomes[i].note + "\n";
      m_kernelSeconds = std::max(m_kernelSeconds, outcomes[i].kernelSeconds);
      m_uploadSeconds = std::max(m_uploadSeconds, outcomes[i].uploadSeconds);
    }
    m_treeAdditions = dplan.additionsPerTile * dplan.tiles;
    result.backendNote = trimmed(m_note);
    result.elapsedS = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    progress.report(1.0, "velocity search, tree (" + name() + ")");
    return result;
  }

  /// The key of a tree plan and workspace: the resident cube (0 when it is not kept: nothing is kept then),
  /// the frame times and offsets, the grid, the cut and the tiling options (FNV-1a).
  std::uint64_t treePlanKey(const search::FilteredCube& cube, const search::VelocityGrid& grid,
                            int cut) const {
    if (m_cubeKey == 0) return 0;
    std::uint64_t h = kFnv1aBasis;
    auto mix = [&h](const void* data, std::size_t bytes) { h = fnv1a(data, bytes, h); };
    const std::vector<double> t = cube.frames.timeOffsetsS();
    const std::vector<PixelOffset> o = cube.frames.frameOffsets();
    mix(t.data(), t.size() * sizeof(double));
    for (const PixelOffset& p : o) {
      mix(&p.x, sizeof p.x);
      mix(&p.y, sizeof p.y);
    }
    const double g[3] = {grid.centre.vx, grid.centre.vy, grid.stepPxS};
    const std::int64_t n[8] = {grid.nvx,
                               grid.nvy,
                               cut,
                               cube.frames.width(),
                               cube.frames.height(),
                               m_options.treeTileRows,
                               static_cast<std::int64_t>(m_options.deviceMemoryLimitBytes),
                               static_cast<std::int64_t>(m_cubeKey)};
    mix(g, sizeof g);
    mix(n, sizeof n);
    return h == 0 ? 1 : h;
  }

  /// Frees every device's tree workspace and the kept plan.
  void releaseTreeWorkspaces() {
    for (std::size_t d = 0; d < m_tree.size(); ++d) {
      if (m_tree[d].bytes() == 0) continue;
      ST_CUDA_CHECK(cudaSetDevice(m_devices[d].ordinal));
      m_tree[d].clear();
    }
    m_treePlan.reset();
    m_treeKey = 0;
  }

  /// Tiles of as many rows as fit in the memory allowed (whole image first), for the first device.
  TreeDevicePlan chooseTreeTiles(const search::TreePlan& tree, const HostPlan& plan,
                                 const search::FilteredCube& cube, std::size_t capacity, int cut) {
    ST_CUDA_CHECK(cudaSetDevice(m_devices.front().ordinal));
    std::size_t freeBytes = 0, totalBytes = 0;
    ST_CUDA_CHECK(cudaMemGetInfo(&freeBytes, &totalBytes));
    constexpr std::size_t kReserve = std::size_t{256} << 20;
    {
      // The cube already resident is counted below as the cube's bytes.
      ResidentSlot& slot = residentSlot(m_devices.front().ordinal);
      std::lock_guard lock(slot.mutex);
      if (slot.holds(m_cubeKey, cube.frames.pixels().size())) freeBytes += slot.cube.bytes();
    }
    std::size_t budget = freeBytes > kReserve ? freeBytes - kReserve : 0;
    if (m_options.deviceMemoryLimitBytes > 0) budget = std::min(budget, m_options.deviceMemoryLimitBytes);
    const std::size_t cubeBytes = cube.frames.pixels().size() * sizeof(float);
    const int h = plan.height;
    std::size_t need = 0;
    // At least one tile per device, so that every device gets work.
    const int first = std::min<int>(h, static_cast<int>(m_devices.size()));
    for (int parts = first; parts <= h;
         parts = parts == h ? h + 1 : std::min(h, parts < 4 ? parts + 1 : parts * 3 / 2)) {
      const int rows = m_options.treeTileRows > 0 ? m_options.treeTileRows : (h + parts - 1) / parts;
      TreeDevicePlan d = makeTreeDevicePlan(tree, plan.width, h, rows, cut);
      need = cubeBytes + treeDeviceBytes(d, plan, capacity);
      if (std::max(d.arenaFloats[0], d.arenaFloats[1]) > kTreeMaxArenaFloats) continue;  // 32-bit offsets
      if (need <= budget || m_options.treeTileRows > 0) {
        if (need > budget) break;
        return d;
      }
    }
    throw GpuError("not enough device memory for the tree search: the cube (" +
                   std::to_string(cubeBytes >> 20) + " MiB) and partial stacks need " +
                   std::to_string(need >> 20) + " MiB, " + std::to_string(budget >> 20) + " MiB allowed");
  }

  static std::string trimmed(std::string s) {
    while (!s.empty() && s.back() == '\n')
      s.pop_back();
    return s;
  }

  /// Cells above threshold kept on the device: CudaOptions::cellCapacity, or max(4 x maxCandidates, 65536).
  std::size_t initialCapacity(const search::SearchParams& params) const {
    return m_options.cellCapacity > 0 ? m_options.cellCapacity
                                      : std::max<std::size_t>(4 * params.maxCandidates, 65536);
  }

  /// Room for all `above` cells, or st::GpuError beyond 2^27 cells (4 GiB).
  static std::size_t checkedCapacity(std::uint64_t above, double threshold) {
    constexpr std::uint64_t kMaxCells = std::uint64_t{1} << 27;  // 4 GiB of cells
    if (above > kMaxCells) {
      throw GpuError(std::to_string(above) + " cells exceed SNR " + std::to_string(threshold) +
                     ": too many to collect on the GPU (raise the threshold)");
    }
    return static_cast<std::size_t>(above);
  }

  /// Runs `work(d, used, report)` on devices [0, used), one host thread each; rethrows the first real error.
  template <class Work>
  std::vector<DeviceOutcome> runOnDevices(int used, ProgressSink& progress, const std::string& stage,
                                          Work work) {
    std::vector<DeviceOutcome> outcomes(static_cast<std::size_t>(used));
    std::vector<std::exception_ptr> errors(static_cast<std::size_t>(used));
    std::vector<double> fractions(static_cast<std::size_t>(used), 0.0);
    std::mutex progressMutex;
    m_abort.store(false);
    auto body = [&](int d) {
      try {
        outcomes[d] = work(d, used, std::function<void(double)>([&, d](double f) {
                             std::lock_guard lock(progressMutex);
                             fractions[d] = f;
                             double sum = 0.0;
                             for (double x : fractions)
                               sum += x;
                             progress.report(sum / used, stage);
                           }));
      } catch (...) {
        errors[d] = std::current_exception();
        m_resources[d].reset();  // work may be left on its streams; made afresh by the next search
        m_tree[d].clear();       // this thread's device is current
        m_abort.store(true);
      }
    };
    std::vector<std::thread> threads;
    for (int d = 1; d < used; ++d)
      threads.emplace_back(body, d);
    body(0);
    for (auto& t : threads)
      t.join();
    rethrowFirst(errors);
    return outcomes;
  }

  /// Rethrows a real error in preference to the Cancelled it caused on the other devices.
  static void rethrowFirst(const std::vector<std::exception_ptr>& errors) {
    std::exception_ptr first;
    for (const auto& e : errors) {
      if (!e) continue;
      try {
        std::rethrow_exception(e);
      } catch (const Cancelled&) {
        if (!first) first = e;
      } catch (...) {
        std::rethrow_exception(e);
      }
    }
    if (first) std::rethrow_exception(first);
  }

  /// IPSA on the first device; CSA (spectral sub-pixel shifts, st::stack::stackCsa) on the CPU, so both
  /// backends give the same CSA stack.
  Image stackAt(const search::FilteredCube& cube, Velocity v, search::StackMode mode) override {
    if (mode == search::StackMode::Csa) {
      NullProgress progress;
      CancelToken cancel;
      return stack::stackCsa(cube.frames, v, progress, cancel).sum;
    }
    return m_stack.stack(cube, v);
  }

 private:
  /// CudaOptions::exactKernel, FramePrecision and the benchmark knobs applied to the automatic plan.
  void applyKernelChoice(HostPlan& plan) const {
    switch (m_options.exactKernel) {
      case ExactKernel::Auto:
      case ExactKernel::Naive:  // DeviceJob::naiveKernel
        break;
      case ExactKernel::Tiled:
        plan.tiledMode = m_bench.tiledMode;
        chooseTiling(plan, false, false);
        break;
      case ExactKernel::Row:
        chooseTiling(plan, true, true);
        break;
      case ExactKernel::StairCpAsync:
        plan.stairTma = false;
        break;
      case ExactKernel::StairFourRows:
        if (!chooseStair(plan, 4)) chooseTiling(plan, true, false);
        break;
      case ExactKernel::AutoNoStair:
        chooseTiling(plan, true, false);  // automatic choice without the stair kernel
        break;
    }
    if (plan.kernel != HostPlan::Kernel::Stair) return;
    if (m_bench.stairPipelined) plan.stairPipe = true;
    if (m_bench.stairMaxFramesPerStage > 0)
      plan.framesPerStage = std::min(plan.framesPerStage, m_bench.stairMaxFramesPerStage);
    if (m_options.precision == FramePrecision::Float16) chooseStairHalf(plan, m_bench.stairMaxFramesPerStage);
  }

  std::vector<DeviceOutcome> runAll(const HostPlan& plan, const search::FilteredCube& cube,
                                    std::size_t capacity, ProgressSink& progress, CancelToken& cancel) {
    const int used = std::min<int>(static_cast<int>(m_devices.size()), plan.nvy);
    return runOnDevices(used, progress, "velocity search (" + name() + ")", [&](int d, int n, auto report) {
      DeviceJob job;
      job.device = m_devices[d].ordinal;
      job.resources = &m_resources[static_cast<std::size_t>(d)];
      job.iyBegin = static_cast<int>(static_cast<long>(plan.nvy) * d / n);
      job.iyEnd = static_cast<int>(static_cast<long>(plan.nvy) * (d + 1) / n);
      job.memoryLimitBytes = m_options.deviceMemoryLimitBytes;
      job.cellCapacity = capacity;
      job.naiveKernel = m_options.exactKernel == ExactKernel::Naive;
      job.uploadChunkBytes = m_options.uploadChunkBytes;
      job.cubeKey = m_cubeKey;
      return runOnDevice(plan, cube.frames.pixels().data(), job, report, cancel, m_abort);
    });
  }

  static void mergeMap(const std::vector<DeviceOutcome>& outcomes, const HostPlan& plan,
                       search::SearchResult& r) {
    const std::size_t nv = static_cast<std::size_t>(plan.nvx) * plan.nvy;
    r.map.nvx = plan.nvx;
    r.map.nvy = plan.nvy;
    r.map.maxSnr.assign(nv, 0.0f);
    r.map.argX.assign(nv, -1);
    r.map.argY.assign(nv, -1);
    std::size_t iv = 0;
    for (const auto& o : outcomes) {
      for (const unsigned long long key : o.mapKeys) {
        if (key != 0ull) {
          const std::uint64_t pixel = hostUnpackIndex(key);
          r.map.maxSnr[iv] = hostUnpackSnr(key);
          r.map.argX[iv] = static_cast<int>(pixel % static_cast<std::uint64_t>(plan.width));
          r.map.argY[iv] = static_cast<int>(pixel / static_cast<std::uint64_t>(plan.width));
        }
        ++iv;
      }
    }
  }

  /// Cells above threshold, as the CPU's search::CellHit (capped and clustered by search::setCandidates).
  static std::vector<search::CellHit> collectCells(const std::vector<DeviceOutcome>& outcomes) {
    std::vector<search::CellHit> cells;
    for (const auto& o : outcomes) {
      for (const DeviceCell& c : o.cells)
        cells.push_back(search::CellHit{c.snr, c.sum, c.x, c.y, c.ivx, c.ivy, c.nIn});
    }
    return cells;
  }

  std::vector<DeviceInfo> m_devices;
  std::vector<std::unique_ptr<DeviceResources>> m_resources;  ///< per device, kept between searches
  CudaOptions m_options;
  CudaBenchOptions m_bench;
  StackEngine m_stack;
  std::string m_note;
  double m_kernelSeconds = 0.0;
  double m_uploadSeconds = 0.0;
  double m_treeAdditions = 0.0;
  std::atomic<bool> m_abort{false};
  std::vector<int> m_ordinals;
  std::uint64_t m_cubeKey = 0;
  std::vector<TreeWorkspace>
      m_tree;  ///< per device: the tree search's arenas and tables, kept (see searchTree)
  std::shared_ptr<const TreeDevicePlan> m_treePlan;  ///< the tree plan those were made for
  std::uint64_t m_treeKey = 0;                       ///< its treePlanKey (0: none kept)
};

}  // namespace

std::unique_ptr<CudaSearchBackend> makeCudaBenchBackend(std::string& whyNot, const CudaOptions& options,
                                                        const CudaBenchOptions& bench) {
  try {
    std::vector<DeviceInfo> devices = usableDevices(whyNot);
    if (devices.empty()) return nullptr;
    return std::make_unique<CudaBackend>(std::move(devices), options, bench);
  } catch (const std::exception& e) {
    whyNot = e.what();
    return nullptr;
  }
}

std::unique_ptr<CudaSearchBackend> makeCudaSearchBackend(std::string& whyNot, const CudaOptions& options) {
  return makeCudaBenchBackend(whyNot, options, CudaBenchOptions{});
}

std::unique_ptr<search::SearchBackend> makeCudaBackend(std::string& whyNot) {
  return makeCudaSearchBackend(whyNot, CudaOptions{});
}

}  // namespace st::gpu

#pragma once
// The CUDA search backend (exact IPSA on every visible GPU). Only plain types cross this header, so it is
// included from app/ without CUDA headers.
//
// What it does (issue 5): the velocity grid is split by rows of vy across every visible device
// (CUDA_VISIBLE_DEVICES is respected, one host thread per device). Each device holds the cube once when it
// fits; otherwise frames are streamed in chunks with partial sums kept on the device, so there is no frame
// cap. Results (per-velocity maxima, cells above threshold) are reduced on the device. Any CUDA failure
// (no driver, out of memory, a failed launch) throws st::GpuError so the caller can fall back to the CPU.
#include <cstddef>
#include <memory>
#include <string>

#include "st/search/types.hpp"

namespace st::gpu {

/// Knobs for tests and benchmarks; the defaults are what the app wants.
struct CudaOptions {
  /// Device memory a search may use on each device, bytes; 0 = what the device has free less 256 MiB.
  /// Tests set it small to force frame and velocity tiling.
  std::size_t deviceMemoryLimitBytes = 0;
  /// Cells above threshold kept on the device per search; 0 = max(4 x maxCandidates, 65536). When more
  /// cells pass the threshold the search is re-run once with room for all of them.
  std::size_t cellCapacity = 0;
  /// Use the naive one-thread-per-(pixel, velocity) reference kernel (benchmarks, tests). Needs the cube
  /// resident on the device.
  bool naiveKernel = false;
  /// Tests and benchmarks: -1 = automatic (the stair kernel when it applies, else the kernel estimated
  /// fastest); -5 = the same, the stair kernel's windows copied by cp.async instead of the TMA; -6 = the
  /// stair kernel with a software-pipelined frame loop (measured slower; benchmarks); -7 = the stair
  /// kernel with at most 8 frames per stage (the earlier sizing; benchmarks); -4 = the
  /// stair kernel with 4-row tiles when it applies; -3 = automatic without the stair kernel; -2 = the row
  /// kernel whenever it applies; 0, 1, 2 = the tiled kernel with inner loop 0 (register reuse by uniform
  /// branches), 1 (no reuse), 2 (reuse by predicated loads); 10, 11, 12 = the same with 64-wide tiles.
  int kernelVariant = -1;
  /// Exact search, cube resident: bytes of frames per upload step, each followed by a launch over the first
  /// velocity rows (0 = 256 MiB). Tests set it small to upload a small cube in several steps.
  std::size_t uploadChunkBytes = 0;
  /// Use at most this many devices (0 = all visible).
  int maxDevices = 0;
  /// Tree search: levels summed in registers by the root kernel (0 = kTreeDefaultCut; at most 4).
  int treeCut = 0;
  /// Tree search: rows per tile (0 = as many as fit in the device memory allowed).
  int treeTileRows = 0;
  /// Tree search: time each level of the first tile and list the times in lastNote() (benchmarks).
  bool profileTree = false;
  /// Tree search, benchmarks: root kernel shape (TreeRootLaunch::shape in gpu/src/tree_kernel_params.hpp),
  /// 0 = the default.
  int treeRootShape = 0;
  /// Keep the cube on each device between searches (and use the one the GPU matched filter left there):
  /// re-searches, the tree search and stackAt of the same cube then upload nothing. Off: every search
  /// uploads (benchmarks of the upload).
  bool keepCubeResident = true;
};

/// Tree search default: the top 4 levels below the root are summed in registers (their stacks are used by
/// about one root velocity each, so storing them would only add memory traffic).
inline constexpr int kTreeDefaultCut = 4;

/// The CUDA backend, with what its last search did about memory (tiling, devices) for the log.
class CudaSearchBackend : public search::SearchBackend {
 public:
  /// "exact" and "tree" (tree_search_device.hpp: the CPU tree's plan, bit-identical stacks).
  [[nodiscard]] bool supportsMethod(const std::string& method) const override {
    return method == "exact" || method == "tree";
  }
  /// One line per device used by the last search: how the cube and the grid were tiled.
  [[nodiscard]] virtual std::string lastNote() const = 0;
  /// Device seconds spent in search kernels by the last search (summed over devices).
  [[nodiscard]] virtual double lastKernelSeconds() const = 0;
  /// Device seconds of the cube's upload in the last tree search (the slowest device).
  [[nodiscard]] virtual double lastUploadSeconds() const = 0;
  /// Additions and copies of the last tree search (levels and root, margins included).
  [[nodiscard]] virtual double lastTreeAdditions() const = 0;
};

/// A CUDA backend over every visible device, or nullptr with `whyNot` set (no device, no driver, a device
/// older than sm_90, ...).
std::unique_ptr<search::SearchBackend> makeCudaBackend(std::string& whyNot);

/// Same, with options, as the CUDA type.
std::unique_ptr<CudaSearchBackend> makeCudaSearchBackend(std::string& whyNot, const CudaOptions& options);

/// One line per visible device ("0: NVIDIA H100 80GB HBM3, 79.1 GiB, sm_90"), or why there is none.
std::string deviceSummary();

}  // namespace st::gpu

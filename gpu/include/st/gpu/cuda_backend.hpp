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

/// The exact search's kernel. The app leaves Auto; tests pick one to check it against the CPU. (Was the
/// int CudaOptions::kernelVariant: -1 Auto, -3 AutoNoStair, -2 Row, 0 Tiled, -4 StairFourRows, -5
/// StairCpAsync, naiveKernel = true Naive; the benchmark-only values are CudaBenchOptions, gpu/src.)
enum class ExactKernel {
  Auto,           ///< the stair kernel when it applies, else the kernel estimated fastest
  AutoNoStair,    ///< the automatic choice without the stair kernel
  Row,            ///< the row kernel whenever it applies
  Tiled,          ///< the tiled kernel (register reuse by uniform branches)
  StairFourRows,  ///< the stair kernel with 4-row pixel tiles when it applies
  StairCpAsync,   ///< the stair kernel with its windows copied by cp.async (what runs when the driver cannot
                  ///< make a tensor map for the TMA)
  Naive,          ///< the one-thread-per-(pixel, velocity) reference kernel; needs the cube resident
};

/// How the exact search's stair kernel stores the frames it reads (issue 16). Float32: the cube as it is
/// (the default; results match the CPU backend to float rounding). Float16: a half-precision copy of the
/// resident cube (values scaled by a power of two near 1/sigma_F, clamped to +-2048 sigma_F), summed in
/// half-precision pairs over the frames of one pipeline stage and in float across stages; its SNR error
/// against Float32 is measured by st_gpu_bench (gpu/README.md). Only the stair kernel with the cube
/// resident and the TMA uses it; any other case runs Float32 and says so in lastNote().
enum class FramePrecision { Float32, Float16 };

/// Knobs for tests and benchmarks; the defaults are what the app wants. Benchmark-only knobs (kernel
/// internals, root kernel shapes, level profiles) are CudaBenchOptions in gpu/src/cuda_bench_options.hpp.
struct CudaOptions {
  /// Device memory a search may use on each device, bytes; 0 = what the device has free less 256 MiB.
  /// Tests set it small to force frame and velocity tiling.
  std::size_t deviceMemoryLimitBytes = 0;
  /// Cells above threshold kept on the device per search; 0 = max(4 x maxCandidates, 65536). When more
  /// cells pass the threshold the search is re-run once with room for all of them.
  std::size_t cellCapacity = 0;
  /// The exact search's kernel (tests).
  ExactKernel exactKernel = ExactKernel::Auto;
  /// Frame storage of the exact search's stair kernel.
  FramePrecision precision = FramePrecision::Float32;
  /// Exact search, cube resident: bytes of frames per upload step, each followed by a launch over the first
  /// velocity rows (0 = 256 MiB). Tests set it small to upload a small cube in several steps.
  std::size_t uploadChunkBytes = 0;
  /// Use at most this many devices (0 = all visible).
  int maxDevices = 0;
  /// Tree search: levels summed in registers by the root kernel (0 = kTreeDefaultCut; at most 4).
  int treeCut = 0;
  /// Tree search: rows per tile (0 = as many as fit in the device memory allowed).
  int treeTileRows = 0;
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

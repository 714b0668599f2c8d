#pragma once
// Benchmark-only knobs of the CUDA backend (issue 18: kept out of the public st/gpu/cuda_backend.hpp). Used
// by gpu/bench/st_gpu_bench.cpp and by white-box tests in tests/gpu (both have gpu/src on their include
// path). The defaults change nothing: makeCudaBenchBackend(whyNot, options, {}) is makeCudaSearchBackend.
#include <memory>
#include <string>

#include "st/gpu/cuda_backend.hpp"

namespace st::gpu {

struct CudaBenchOptions {
  /// Tiled kernel's inner loop (SearchLaunch::variant) when CudaOptions::exactKernel is Tiled: 0 register
  /// reuse by uniform branches (the default), 1 no reuse, 2 reuse by predicated loads; 10, 11, 12 the same
  /// with 64-wide tiles.
  int tiledMode = 0;
  /// Stair kernel: software-pipelined frame loop (measured slower, 2026-11-22; was kernelVariant -6).
  bool stairPipelined = false;
  /// Stair kernel: at most this many frames per pipeline stage (0 = as many as fit; 8 was the sizing before
  /// 2026-11-22 06:30, kernelVariant -7).
  int stairMaxFramesPerStage = 0;
  /// Tree search: root kernel shape (TreeRootLaunch::shape, tree_kernel_params.hpp), 0 = the default.
  int treeRootShape = 0;
  /// Tree search: direct nodes summed frame by frame from the tables (the level kernel before 2026-11-27).
  bool treeDirectPlain = false;
  /// Tree search: time each level of the first tile and list the times in lastNote().
  bool profileTree = false;
};

/// makeCudaSearchBackend with benchmark knobs.
std::unique_ptr<CudaSearchBackend> makeCudaBenchBackend(std::string& whyNot, const CudaOptions& options,
                                                        const CudaBenchOptions& bench);

}  // namespace st::gpu

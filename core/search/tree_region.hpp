#pragma once
// Private to core/search: the tree search over a region of the cube's pixels (the owned part of an
// out-of-core tile, tiled_search.hpp), the same cells and values as the whole-image tree search gives there.
#include "ipsa_kernel.hpp"

namespace st::search::detail {

struct TreeRegionParams {
  double sigmaF = 1.0;
  double snrThreshold = 7.0;
  int minFrames = 1;
  std::size_t maxHits = 10000;
  std::size_t bufferBytes = 0;  ///< partial stacks of all threads together (0: kTreeBuffersBytes)
  unsigned threads = 0;         ///< at most this many threads (0: workerCount()), SearchParams::treeThreads
};

/// Tree search of output cells in `roi` (the frames around it are read as the image: samples outside the
/// cube are out of the frame). Map and hits as runIpsaKernel's. Throws st::Cancelled.
KernelOutput treeSearchRegion(const FrameCube& frames, const VelocityGrid& grid, const Roi& roi,
                              const TreeRegionParams& params, ProgressSink& progress, CancelToken& cancel);

}  // namespace st::search::detail

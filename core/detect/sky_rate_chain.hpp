#pragma once
// Internal to the sky-rate measurement: the chained refinement (st/detect/sky_rate.hpp describes it).
#include <string>
#include <vector>

#include "st/detect/sky_rate.hpp"

namespace st::detect::detail {

struct ChainResult {
  bool ok = false;
  Velocity rate;                     ///< px/s, when ok
  double response = 0.0;             ///< median phase-correlation peak over the links
  std::vector<SkyRateBlock> blocks;  ///< with their offsets from the linear model, when ok
  double residualRmsPx = 0.0;
  int links = 0;       ///< block comparisons used (last iteration)
  int starLinks = 0;   ///< ... of which by the paired stars' windowed centroids (the others: phase peak)
  std::string why;     ///< why it failed, when !ok
  int iterations = 0;  ///< stacks-and-links rounds run
  /// Over the iterations after the first: the block stacks and the links kept from the one before (their
  /// blocks' frames kept their whole-pixel shifts: the same images, hence the same measurement).
  int stacksKept = 0, linksKept = 0;
  bool coarseFirst = false;  ///< the first iteration linked neighbouring blocks only (SkyRateParams)
  /// Over all iterations: the wall time of the blocks' stacks and of the links, and the links' thread time
  /// in their images, phase correlations and paired stars (SkyRate::parts).
  TimedParts parts;
};

/// detect::shiftedSums of one block into rows [y0, y1) of `sum` and `cnt` (frame-sized, zeroed there; each
/// pixel takes the block's frames in order, AVX2 where the CPU has it).
void addShifted(const FrameCube& cube, const ShiftedBlock& blk, double background, double* sum, double* cnt,
                int y0, int y1);

/// Chains blocks of `cube` starting from `start` (px/s): see measureSkyRate. Not ok (with `why`) when
/// the cube is too short for two blocks or the blocks cannot all be linked.
ChainResult chainSkyRate(const FrameCube& cube, Velocity start, double background, double sigma,
                         const SkyRateParams& params, CancelToken& cancel,
                         const ShiftedSumsProvider* sums = nullptr,
                         const PhaseCorrelationProvider* correlate = nullptr);

}  // namespace st::detect::detail

#pragma once
// Cosmic rays (paper §4.2): "Cosmic ray events are detected by first zeroing out the bright stars ... We
// differentiate the bright stars from the cosmic ray events by integrating over hundreds of frames ... After
// zeroing the signals from the bright stars, differences between consecutive frames are used to identify
// highly varying signals on the frame-to-frame basis." Here stars are protected (not zeroed) by a mask made
// from stacks at the sky rate; a pixel is a hit when it stands above both of its neighbours in time.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "st/common/frame_cube.hpp"
#include "st/common/progress.hpp"
#include "st/common/units.hpp"

namespace st::calib {

struct CosmicRayParams {
  double thresholdSigma = 7.0;  ///< hit: F_n - max(two nearest frames) > thresholdSigma * sigma (one frame)
  double growSigma = 5.0;       ///< 8-neighbours of a hit above this join it (tracks, charge spread)
  double protectSnr = 5.0;      ///< pixels whose SNR is >= this in every one of `protectBlocks` sky-rate
                                ///< stacks are protected (a star is in every block, a hit in one)
  int protectBlocks = 3;
  int protectDilatePx = 2;
  double protectedExcess = 1.0;  ///< on a protected pixel a hit must also exceed this times the star signal
  Velocity skyRate;              ///< px/s, so that protection follows drifting stars
  enum class Fill { Zero, TimeNeighbours };
  /// Zero (the paper) for zero-biased frames; TimeNeighbours (mean of the two frames used as reference) when
  /// the background has not been subtracted yet, so that the per-pixel clip is not pulled down. The pipeline
  /// uses TimeNeighbours and zeroes the listed pixels after background subtraction.
  Fill fill = Fill::Zero;
};

struct CosmicRayResult {
  std::vector<std::size_t> perFrame;  ///< pixels flagged in each frame
  std::size_t total = 0;
  std::vector<std::uint64_t> pixels;  ///< flat indices n * width * height + y * width + x, sorted
  std::size_t protectedPixels = 0;    ///< reference positions protected as stars
  double sigma = 0.0;                 ///< single-frame noise from frame differences, counts
};

/// Finds and removes cosmic-ray hits in place. Needs >= 3 frames (fewer: nothing is done, total 0).
/// Masked pixels are never flagged. Throws st::Cancelled.
CosmicRayResult removeCosmicRays(FrameCube& cube, const CosmicRayParams& params, ProgressSink& progress,
                                 CancelToken& cancel);

/// Sets the listed pixels (flat cube indices) to 0.
void zeroPixels(FrameCube& cube, const std::vector<std::uint64_t>& pixels);

/// Single-frame noise from differences of frame pairs (symmetric clip, xi = 5, / sqrt 2), unmasked pixels.
double noiseFromFrameDifferences(const FrameCube& cube);

}  // namespace st::calib

#pragma once
// The sky rate: how fast the stars move across the detector (px/s). Zero for a tracked telescope; the drift
// rate when the sky moves (paper §4.1: scanning at 5"/s). Measured from the stars when not given.
#include <string>

#include "st/common/frame_cube.hpp"
#include "st/common/progress.hpp"
#include "st/common/units.hpp"

namespace st::detect {

struct SkyRateParams {
  int blocks = 8;             ///< pairs of adjacent blocks, spread evenly over the cube
  int blockFrames = 12;       ///< frames per block at most (short, so that drifting stars streak little)
  double detectSigma = 5.0;   ///< pixels below this SNR in a block mean are zeroed (keep the stars)
  double minResponse = 0.03;  ///< phase-correlation peak below this: no reliable stars, rate 0
};

struct SkyRate {
  Velocity rate;          ///< px/s
  bool reliable = false;  ///< false when no star pattern was found (rate is then 0)
  double response = 0.0;  ///< phase-correlation peak of the final measurement
  std::string note;       ///< how it was measured, for the user
};

/// Measures the sky rate by phase correlation (OpenCV) of the means of blocks of frames with the global
/// background `background` removed and faint pixels (< detectSigma * sigma / sqrt(frames in block)) zeroed:
/// pairs of short adjacent blocks (median over pairs) give a first rate (robust to large drifts; each block
/// is the smaller of the means of its two halves so that cosmic rays drop out); then stacks at that rate of
/// the first and last thirds of the frames are phase-correlated (stars coincide when the rate is right) and
/// the residual offset, with the stacks' integer shifts, over their time separation gives the rate (up to 4
/// times, until the integer shifts stay the same). Wherever >= 3 bright sources (peak >= 4x the threshold,
/// >= 4 px) pair up, the offset is their median centroid offset, one vote per source, instead of the phase
/// correlation's sub-pixel peak: a bright moving object (a streak in every block) pulls that peak, not the
/// median (tested: a magnitude-14 mover among the "small" preset's stars, within 0.02 px/s of the truth).
SkyRate measureSkyRate(const FrameCube& cube, double background, double sigma, const SkyRateParams& params,
                       CancelToken& cancel);

}  // namespace st::detect

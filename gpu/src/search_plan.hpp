#pragma once
// Host side of the CUDA search: converts the core types (FilteredCube, VelocityGrid, SearchParams) into the
// plain tables the kernels read (shifts, N_in spans, normalisation) and chooses the kernel tiling.
#include <cstddef>
#include <string>
#include <vector>

#include "st/search/types.hpp"

namespace st::gpu {

struct HostPlan {
  int width = 0;
  int height = 0;
  int frameCount = 0;
  int nvx = 0;
  int nvy = 0;
  std::vector<int> shiftX;  ///< [nvx][N] round(vx dt_n), halves away from zero (std::lround)
  std::vector<int> shiftY;  ///< [nvy][N]
  std::vector<int> spanX;   ///< [nvx][W][2] inclusive range of time-ordered frames keeping column x in frame
  std::vector<int> spanY;   ///< [nvy][H][2] same for rows
  std::vector<float> invNorm;  ///< [N + 1] float(1 / (sigma_F sqrt(n)))
  float snrThreshold = 0.0f;   ///< cells strictly above are candidates
  int minFrames = 1;           ///< cells with fewer contributing frames are ignored
  // Tiling of the tiled kernel (useTiled false: the shift spread is too large for shared memory and the
  // naive kernel is used instead; slower, same result).
  bool useTiled = true;
  int vtileX = 8;
  int vtileY = 1;
  int pitch = 0;
  int winRows = 0;
  int framesPerStage = 1;
};

/// Builds the tables for `cube` and `grid`. `threshold` is the SNR threshold actually used and
/// `minFrames` the N_in floor (both as the CPU backend derives them). Throws st::InputError on bad input.
HostPlan makeHostPlan(const search::FilteredCube& cube, const search::VelocityGrid& grid, double threshold,
                      int minFrames);

/// The SNR threshold actually used: from params.targetFap (paper \label{Prob_false}) when set, else
/// params.snrThreshold.
double effectiveSnrThreshold(const search::SearchParams& params, const search::TrialCounts& trials);

/// ceil(minFrameFraction * N_f), at least 1.
int minFramesFor(const search::SearchParams& params, std::size_t frames);

/// Detection false-alarm probability, paper \label{Prob_false}: N_x N_y N_vx N_vy erfc(SNR / sqrt 2) / 2.
double detectionFap(double snr, const search::TrialCounts& trials);

/// Validates the search inputs; throws st::InputError naming the value at fault.
void validateSearch(const search::FilteredCube& cube, const search::VelocityGrid& grid,
                    const search::SearchParams& params);

}  // namespace st::gpu

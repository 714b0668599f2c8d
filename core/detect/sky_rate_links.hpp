#pragma once
// Internal to the sky-rate measurement: the chain's blocks and the links between them (sky_rate_chain.cpp
// stacks the blocks and solves for the rate; sky_rate_links.cpp measures the links).
#include <cstddef>
#include <vector>

#include <opencv2/core.hpp>

#include "st/common/timed_parts.hpp"
#include "st/detect/sky_rate.hpp"

namespace st::detect::detail {

// One block stacked at the current rate about its own mean time: a star at x_ref + u t in the frames sits
// in the stack at x_ref + u tS - meanShift (u the true rate), since frame n is shifted by the whole pixels
// round(v (t_n - tS)) of the current rate v. Single precision, 9 bytes a pixel: every block is held at once.
struct BlockStack {
  cv::Mat value;    // CV_32F, mean of F_n - background where covered, else 0
  cv::Mat noise;    // CV_32F, sigma / sqrt(frames contributing)
  cv::Mat covered;  // CV_8U, 255 where (nearly) every frame of the block contributed
  double tS = 0.0;  // mean t_n - t_ref over the block
  cv::Point2d meanShift;
};

// A comparison of blocks i and j.
struct Link {
  std::size_t i = 0, j = 0;
  cv::Point2d d;    // P_j - P_i, px: the star field's motion from block i to block j
  cv::Point2d var;  // its variance along x and y, px^2
  double response = 0.0;
  bool byStars = false;  // from the paired stars' windowed centroids (else the phase correlation's peak)
  int gx = 0, gy = 0;    // the whole pixels block j's stack was moved by, as the rate predicts
};

/// The links an iteration tried (measureLinks' own record), and which of them held.
struct TriedLinks {
  std::vector<Link> links;
  std::vector<char> ok;
};

/// True when the links connect every block to block 0.
bool connected(std::size_t blocks, const std::vector<Link>& links);

/// The links of one iteration: every pair of blocks whose stars have moved at most linkFraction of the frame
/// between them (neighbours always), measured in parallel (their phase correlations by `correlate` where it
/// makes them); failed comparisons are left out. `threadTime` gets the links' parts summed over threads.
/// A link between two blocks whose stacks the previous iteration had too (`sameStacks`), moved by the same
/// whole pixels, is taken from `tried` as that iteration measured it (the same images: the same result),
/// and counted in `*kept`; `tried` then records this iteration's links. `neighboursOnly`: only blocks i and
/// i + 1.
std::vector<Link> measureLinks(const std::vector<BlockStack>& stacks, Velocity rate, const cv::Mat& window,
                               const SkyRateParams& params, int width, int height, CancelToken& cancel,
                               const PhaseCorrelationProvider* correlate, TimedParts* threadTime,
                               const std::vector<char>& sameStacks, TriedLinks& tried, int* kept,
                               bool neighboursOnly = false);

}  // namespace st::detect::detail

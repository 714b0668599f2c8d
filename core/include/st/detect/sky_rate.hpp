#pragma once
// The sky rate: how fast the stars move across the detector (px/s). Zero for a tracked telescope; the drift
// rate when the sky moves (paper §4.1: scanning at 5"/s). Measured from the stars when not given.
#include <cstddef>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "st/common/timed_parts.hpp"
#include "st/common/frame_cube.hpp"
#include "st/common/progress.hpp"
#include "st/common/units.hpp"

namespace st::detect {

struct SkyRateParams {
  int blocks = 8;             ///< pairs of adjacent blocks, spread evenly over the cube
  int blockFrames = 12;       ///< frames per block at most (short, so that drifting stars streak little)
  double detectSigma = 5.0;   ///< pixels below this SNR in a block mean are zeroed (keep the stars)
  double minResponse = 0.03;  ///< phase-correlation peak below this: no reliable stars, rate 0
  int chainMinBlocks = 4;     ///< the chained refinement cuts the cube into at least this many blocks ...
  double chainStepFraction = 0.15;  ///< ... and into enough that the stars move at most this fraction of
                                    ///< the frame between neighbouring blocks (so that they share stars)
  double chainLinkFraction = 0.5;   ///< blocks are compared when the stars move at most this fraction of
                                    ///< the frame between them (neighbours always); never beyond
  int chainMinBlockFrames = 4;      ///< frames per block at least
  /// An iteration after the first keeps the stacks of the blocks whose frames keep their whole-pixel shifts,
  /// and the links between them (the same images give the same measurement); false measures all again (the
  /// tests' reference).
  bool chainKeepUnchanged = true;
  /// The first iteration links only neighbouring blocks: its rate only sets the next iteration's stacks,
  /// and the blocks' neighbours link them all. False links every pair in every iteration (the tests'
  /// reference, with chainKeepUnchanged false the chain as it was before 2026-12-02's eleventh stop).
  bool chainCoarseFirst = true;
};

/// One block of contiguous frames of the chained refinement, and where its stars were found.
struct SkyRateBlock {
  std::size_t firstFrame = 0;  ///< frames [firstFrame, lastFrame)
  std::size_t lastFrame = 0;
  double tS = 0.0;    ///< mean of the block's t_n - t_ref, s
  Velocity offsetPx;  ///< the star field's measured position minus the linear model's at tS, px (x, y)
};

struct SkyRate {
  Velocity rate;           ///< px/s
  bool reliable = false;   ///< false when no star pattern was found (rate is then 0)
  double response = 0.0;   ///< phase-correlation peak of the final measurement
  std::string note;        ///< how it was measured, for the user
  bool chained = false;    ///< true when the rate is the chained refinement's (else the block pairs')
  Velocity blockPairRate;  ///< the first estimate, from pairs of short adjacent blocks, px/s
  /// The chained blocks (empty when the chain failed): per-block departures of the star field from the
  /// linear motion, for a later per-frame registration (ARCHITECTURE.md's o_n); not used by the search.
  std::vector<SkyRateBlock> blocks;
  double residualRmsPx = 0.0;  ///< rms over blocks of |offsetPx| (both axes), px
  /// Wall time of the parts, for the notes: the block pairs (their means and phase correlations), the chain
  /// and of it the blocks' stacks and the links; and the links' thread time (summed over the threads) in
  /// their images, phase correlations and paired stars.
  TimedParts parts;
};

/// A block of frames [first, last) stacked with frame n shifted so that stack pixel (x, y) takes frame pixel
/// (x + sx[n - first], y + sy[n - first]) (the chained refinement's block stacks).
struct ShiftedBlock {
  std::size_t first = 0, last = 0;
  std::vector<int> sx, sy;
};

/// Per stack pixel (row-major, the frame's size): the sum of (F_n - background) over the block's unmasked
/// samples that fall inside their frame, in frame order, and their count. A device may give instead the
/// block's mean, sum / count rounded to float (0 where the count is 0), and the count as a float (a whole
/// number of frames: exact), in `mean` and `frames` (sum and count empty): what the block's stack takes from
/// the sums, in half the bytes (issue 16).
/// Asked for with ShiftedSumsForm::DoubleMeans instead: the block's mean in double, sum / count (0 where
/// the count is 0), the same division of the same sums as the host's (the block pairs' images, issue 16).
struct ShiftedSums {
  std::vector<double> sum, count;
  std::vector<float> mean, frames;
  std::vector<double> doubleMean;
};

/// What a ShiftedSumsProvider is asked to return per block.
enum class ShiftedSumsForm {
  SumsOrMeans,  ///< sum and count, or mean and frames (the chain's block stacks take either)
  DoubleMeans,  ///< doubleMean (the block pairs' means)
};

/// shiftedSums' means in the form DoubleMeans asks for (sum / count, 0 where the count is 0).
std::vector<double> doubleMeans(const ShiftedSums& sums);

/// shiftedSums on the CPU (the reference).
std::vector<ShiftedSums> shiftedSums(const FrameCube& cube, const std::vector<ShiftedBlock>& blocks,
                                     double background);

/// Makes every block's sums elsewhere (a device, issue 16) in the form asked for: for SumsOrMeans
/// shiftedSums' result, or the blocks' means and counts (ShiftedSums::mean, frames) made from it; for
/// DoubleMeans ShiftedSums::doubleMean. None: not made there, the CPU makes them.
using ShiftedSumsProvider = std::function<std::optional<std::vector<ShiftedSums>>(
    const FrameCube& cube, const std::vector<ShiftedBlock>& blocks, double background, ShiftedSumsForm form)>;

/// The chain's phase correlations of one iteration, for a device (issue 16): `pairs` pairs of images of
/// width x height, each correlated as the CPU's does (cv::phaseCorrelate's zero padding to nx x ny, the
/// normalised cross-power spectrum, its first largest value in the quadrant-swapped order and the 5 x 5
/// centroid around it).
struct PhaseCorrelationBatch {
  int width = 0, height = 0;
  int nx = 0, ny = 0;  ///< the transform sizes (cv::getOptimalDFTSize of width and height)
  std::size_t pairs = 0;
  /// Writes pair p's two images, the window applied, as width x height floats (row-major) into a and b: the
  /// FFT's input on the CPU. Called from several threads at once, once for each p.
  std::function<void(std::size_t p, float* a, float* b)> fill;
};

/// One pair's phase correlation: the offset of b relative to a (px) and the response. `ok` false: not made
/// there (a surface that was not finite, as the CPU's handles apart), the CPU correlates that pair.
struct PhasePeak {
  double dx = 0.0, dy = 0.0, response = 0.0;
  bool ok = false;
};

/// Correlates a batch elsewhere (a device: the transforms' floats differ from FFTW's by rounding, so the
/// offsets within ~1e-4 px and the responses within ~1e-5 of the CPU's). None: the CPU does them all.
using PhaseCorrelationProvider =
    std::function<std::optional<std::vector<PhasePeak>>(const PhaseCorrelationBatch& batch)>;

/// Measures the sky rate from the stars, with the global background `background` removed and faint pixels
/// (< detectSigma * sigma / sqrt(frames averaged)) zeroed.
/// First estimate: phase correlation (OpenCV) of pairs of short adjacent blocks spread over the cube (median
/// over pairs; each block is the smaller of the means of its two halves so that cosmic rays drop out;
/// wherever >= 3 bright sources pair up, their median centroid offset replaces the correlation's sub-pixel
/// peak, which a bright mover pulls). Robust to large drifts, good to ~0.5 px/s.
/// Then the chained refinement: the cube is cut into contiguous blocks (chainMinBlocks at least, more when
/// the stars would move more than chainStepFraction of the frame between neighbours), each stacked at the
/// current rate about its own mean time, only where (nearly) all its frames contribute. Blocks whose stars
/// move at most chainLinkFraction of the frame between them (neighbours always) are compared: block j's
/// stack moved by the predicted whole pixels, the residual offset from the phase correlation, then from
/// Gaussian-windowed centroids of the paired stars on the linear stacks (saturated, flat-topped ones left
/// out; estimates > 3 sigma + 0.1 px from their median dropped, so that a mover does not count; the rest
/// averaged by inverse variance). A weighted least-squares solve over the links gives each block's position
/// of the star field, a straight line through them the rate and each block's departure (offsetPx);
/// iterated (up to 4 times) until the stacks' whole-pixel shifts stay the same. Blocks that share no stars
/// are never compared, so the field may change completely over the sequence. The chain is kept when every
/// block is linked and its rate agrees with the first estimate (within 3 times the pairs' robust scatter and
/// 1 px over a pair's time span); otherwise the first estimate is kept and the note says why.
/// Tested: paper-neo seeds 1..21 (500 frames, 16.4 px/s, the field moving 490 px of 512) within 0.004
/// px/s of the truth, the 1500-frame seed 5 within 0.001 (tests/core/test_detect_sky_rate_slow.cpp); a
/// synthetic field crossing the frame 3.7 times within 0.01; a magnitude-14 mover among the "small" preset's
/// stars within 0.02 px/s.
/// `sums`, when given, makes the block pairs' means (DoubleMeans: blocks with no shifts) and the chain's
/// block stacks (the same sums: the same result). `correlate`, when given, makes the chain's links' phase
/// correlations (an offset the paired stars' centroids replace on nearly every link; the block pairs' stay on
/// the CPU, where the correlation's offset is the result whenever the stars' consensus fails).
SkyRate measureSkyRate(const FrameCube& cube, double background, double sigma, const SkyRateParams& params,
                       CancelToken& cancel, const ShiftedSumsProvider* sums = nullptr,
                       const PhaseCorrelationProvider* correlate = nullptr);

}  // namespace st::detect

#pragma once
// The matched filter (paper §4.3, last sentence): every zero-biased frame is convolved with the PSF before
// the velocity search. The kernel is the Moffat PSF averaged over each pixel (what the detector records
// for a star of unit peak), truncated where P < kDefaultTruncation of its peak; a Moffat is not separable,
// so the convolution is a 2-D one, by FFT (FFTW, zero-padded: the linear convolution with zeros outside the
// frame; test_stack_filter checks it against the direct sum).
// A source alpha * K then filters to a peak alpha * sum K^2, and white noise sigma_n to
// sigma_n * sqrt(sum K^2); real frames have correlated, masked noise, so sigma_F is always measured from
// the filtered data (ARCHITECTURE.md, SNR convention).
#include <cstddef>
#include <vector>

#include "st/common/frame_cube.hpp"
#include "st/common/image.hpp"
#include "st/common/progress.hpp"
#include "st/psf/moffat.hpp"
#include "st/search/types.hpp"
#include "st/stats/noise_model.hpp"

namespace st::stack {

/// P below 1e-3 of its peak no longer matters: beyond that radius the kernel holds < 0.3% of sum P^2 for
/// beta = 4 (and its noise contribution is below float rounding of the sum for typical frames).
inline constexpr double kDefaultTruncation = 1e-3;

/// The matched-filter kernel: (2 halfSize + 1)^2 pixels, centre at (halfSize, halfSize), the pixel mean of
/// P (peak of the continuous profile 1), set to 0 where the point value P < truncation (a disc).
struct FilterKernel {
  Image kernel;
  int halfSize = 0;
  double sumSquares = 0.0;  ///< sum K^2: the filtered peak of a unit-amplitude source, and the white-noise
                            ///< variance gain
  double sum = 0.0;         ///< sum K
};

/// Builds the kernel for `psf`, truncated at `truncation` x peak (default kDefaultTruncation). Throws
/// st::InputError for a non-positive truncation or a PSF of non-positive R or beta <= 1.
FilterKernel makeFilterKernel(const psf::Moffat& psf, double truncation = kDefaultTruncation);

/// Convolves one frame (width x height, row-major, in place) with the kernel; samples outside the frame
/// count as 0 (the frames are zero-biased). Plans its FFT for this one frame: filterCube, which plans once
/// for the cube, is the way to filter many.
void filterFrame(float* frame, int width, int height, const FilterKernel& kernel);

/// What filterCube measured.
struct MatchedFilterResult {
  double sigmaF = 0.0;           ///< noise of one filtered frame: rms over frames of each one's 1.4826 x MAD
  std::size_t noiseSamples = 0;  ///< pixels that entered sigmaF
  int kernelHalfSize = 0;
  double kernelSumSquares = 0.0;
};

/// Filters every frame of `cube` in place (parallel over frames; one padded FFT buffer per thread, no second
/// cube). With a noise model (variance s_n^2 v(q) of frame n at pixel q, stats/noise_model.hpp) the filter is
/// the inverse-variance-weighted one: psi_n = K conv (F_n / (s_n^2 v)), and the output is
/// psi_n sigma_ref sqrt(sum K^2) / sqrt(Phi) with Phi = K^2 conv omega, omega(q) = (1/v(q)) x the mean over
/// frames of [q used in frame n] / s_n^2. The search's S / (sigma_F sqrt(N_in)) along a track then equals the
/// likelihood statistic sum psi / sqrt(sum phi) (Whidden et al. 2019) wherever Phi is constant along the
/// track (noise separable into a frame factor and a smooth map); for uniform noise sigma (v = sigma^2,
/// s_n = 1) the output is exactly the unweighted K conv F away from edges and zeroed pixels, and sigma_F is
/// sigma sqrt(sum K^2) everywhere: every pixel is scaled to the same noise, so vignetted corners and noisy
/// frames neither raise false alarms nor dilute the rest. Masked and non-finite pixels are set to 0 first.
/// sigma_F is measured on up to 64 frames spread over the cube from every 3rd pixel that is at least halfSize
/// away from the frame edge and from any zero/masked input pixel (there the noise is lower and would bias
/// sigma_F). Reports progress; throws st::Cancelled, and st::InputError when too few pixels are left to
/// measure sigma_F (< 1000).
MatchedFilterResult filterCube(FrameCube& cube, const FilterKernel& kernel, ProgressSink& progress,
                               CancelToken& cancel, const stats::NoiseModel* noise = nullptr);

/// The frames filterCube samples for sigma_F (up to 64 spread over `frameCount`, ascending).
std::vector<std::size_t> filterNoiseFrames(std::size_t frameCount);

/// filterCube's sigma_F from the samples of each frame of filterNoiseFrames (in that order; each frame's
/// values in any order, consumed), for a device implementation of filterCube. Same errors as filterCube.
MatchedFilterResult filterNoiseFromSamples(std::vector<std::vector<float>>& samples, const FilterKernel& kernel);

/// Robust noise (1.4826 x MAD about the median) of already-filtered frames: non-zero pixels of up to
/// maxFrames frames spread over the cube, every `stride`-th pixel, `border` px from the edges. Returns 0 when
/// fewer than 1000 pixels qualify.
double measureFilteredNoise(const FrameCube& cube, int border, std::size_t maxFrames = 64, int stride = 3);

/// The search's input in one call: takes `prepared` (zero-biased frames with static sources and cosmic
/// rays zeroed; moved in, not copied), filters it in place with the kernel of `psf` (kDefaultTruncation)
/// and fills sigmaF (filterCube), skyRate and psfFwhmPx. Same errors as filterCube.
search::FilteredCube makeFilteredCube(FrameCube prepared, const psf::Moffat& psf, Velocity skyRate,
                                      ProgressSink& progress, CancelToken& cancel);

}  // namespace st::stack

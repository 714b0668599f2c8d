#pragma once
// What injection needs to know about the field of an observation, measured on its calibrated frames: the
// PSF (Moffat fits on stars, st::psf), where the stars are (a simple detection on the median frame), and
// the local frame-to-frame noise around a track.
#include <cstdint>
#include <optional>
#include <vector>

#include "st/common/frame_cube.hpp"
#include "st/common/image.hpp"
#include "st/common/progress.hpp"
#include "st/io/sections.hpp"
#include "st/psf/moffat.hpp"

namespace st::inject {

struct FieldParams {
  std::optional<psf::Moffat> psf;  ///< given by the user: no PSF fit
  double starThresholdSigma = 5.0; ///< a star pixel: median frame above its mesh background + this x noise
  int meshPx = 32;                 ///< cell of the median frame's background (per-cell median, bilinear)
  int psfFrames = 9;               ///< frames (evenly spaced) the PSF is fitted on
};

struct Field {
  int width = 0;   ///< calibrated frame size
  int height = 0;
  psf::Moffat psf;                 ///< measured (median-FWHM frame's fit) or given
  bool psfMeasured = false;
  std::vector<double> psfFwhmPerFramePx;  ///< FWHM of each frame's fit that succeeded, px
  std::vector<std::uint8_t> mask;  ///< row-major; 1 = star pixel of the median frame or a bad pixel
  std::vector<float> maskDistancePx;  ///< distance from each pixel centre to the nearest masked pixel, px
  std::size_t maskedPixels = 0;
  double medianFrameNoise = 0.0;   ///< robust noise of the median frame after its background, counts
};

/// Measures the field of `calibrated` (bias/flat-corrected, trimmed, frames in calibrated counts): the
/// per-pixel median frame (unmasked samples), its mesh background (median of meshPx cells, bilinear
/// between cell centres), star pixels above starThresholdSigma x the robust noise of the difference,
/// pixels masked in any frame, the distance map to them; and the PSF: psf::measurePsf on up to psfFrames
/// frames spread evenly over the cube (each with its own star candidates), the fit of the frame with the
/// median FWHM (frames without a usable star are skipped). Throws st::InputError when no frame has a usable star and no PSF was given ("give --fwhm"),
/// or when the cube has fewer than 3 frames. Throws st::Cancelled.
Field measureField(const FrameCube& calibrated, const FieldParams& params, ProgressSink& progress,
                   CancelToken& cancel);

/// The local noise of each frame in `region` (counts), from the frame-to-frame scatter of its pixels:
/// each frame's median over the region's usable pixels (mask == 0 and not masked in the cube) is taken out
/// (sky offsets between frames are not noise), then every pixel's median over the frames, and sigma_n is
/// 1.4826 x the MAD of frame n's residuals over the region, divided by residualScale(N) (a residual about
/// a median of N samples that include it is smaller than the noise).
/// Throws st::InputError when the region holds fewer than 50 usable pixels or the cube fewer than 3 frames.
std::vector<double> localFrameNoise(const FrameCube& calibrated, const std::vector<std::uint8_t>& mask,
                                    const io::PixelRegion& region);

/// 1.4826 x MAD of x_n - median(x_1..x_N) for unit Gaussian noise: the factor by which localFrameNoise's
/// residuals understate the noise (0.93 for N = 15; for odd N the median is one of the samples, whose
/// residual is then 0). Computed once per N by a seeded Monte Carlo (200000 residuals, error ~0.2%).
double residualScale(std::size_t frames);

/// The background of an image: the median of each meshPx x meshPx cell (pixels with mask == 0, exact
/// zeros and non-finite values left out), interpolated bilinearly between cell centres. Cells without
/// usable pixels take the median of the cell medians.
Image meshBackground(const Image& image, const std::vector<std::uint8_t>& mask, int meshPx);

}  // namespace st::inject

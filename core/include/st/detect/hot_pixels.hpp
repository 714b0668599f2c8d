#pragma once
// Hot pixels found from the science frames themselves (when no dark frame is given): a pixel that is bright
// in every part of the observation (unlike a cosmic ray) and much sharper than the PSF (unlike a star: its
// 4-neighbours are not raised). Drifting stars and the moving object are never at one pixel all the time.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "st/common/frame_cube.hpp"
#include "st/common/progress.hpp"

namespace st::detect {

struct HotPixelParams {
  int blocks = 3;          ///< the frames are cut into this many blocks; a hot pixel is high in each
  double snr = 5.0;        ///< block-mean excess over the background, in block-mean sigmas
  double sharpness = 3.0;  ///< excess must exceed this times the largest 4-neighbour excess
};

/// Indices (y * width + x) of hot pixels. `background` and `sigma` are the global clip estimates (one frame).
std::vector<std::size_t> findHotPixels(const FrameCube& cube, double background, double sigma,
                                       const HotPixelParams& params, CancelToken& cancel);

/// findHotPixels's selection from each pixel's smallest block-mean excess over `background` (`minExcess`,
/// width x height; the excess of block b = float(sum of the pixel's unmasked samples of frames
/// [nf b / blocks, nf (b + 1) / blocks) in frame order, in double, / their count - background), 0 without
/// samples), so that a device may compute the excess and the CPU's own selection picks the pixels.
std::vector<std::size_t> hotPixelsFromExcess(const std::vector<float>& minExcess, int width, int height,
                                             std::size_t frames, double sigma, const HotPixelParams& params);

/// Masks the given pixels in every frame (allocates the cube's mask when needed). Returns how many.
std::size_t maskPixelsInAllFrames(FrameCube& cube, const std::vector<std::size_t>& pixels);

}  // namespace st::detect

#pragma once
// FrameCube: the observation, float32 frames held once, row-major and contiguous (frame n, row y, column x
// at index (n * height + y) * width + x). Each frame carries its exposure mid-time (MJD, UTC) and length and
// where it came from. The reference epoch t_ref is the mean of the mid-times (ARCHITECTURE.md).
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "st/common/fits_header.hpp"
#include "st/common/image.hpp"
#include "st/common/pixel_vector.hpp"

namespace st {

class Wcs;  // st/io/wcs.hpp

struct FrameInfo {
  double mjdMid = 0.0;     ///< exposure mid-time, MJD (UTC)
  double exposureS = 0.0;  ///< exposure length, seconds
  std::string file;        ///< file the frame was read from (empty when made in memory)
  int hdu = 0;             ///< 1-based HDU number in that file (CFITSIO's numbering)
  int plane = 0;           ///< 0-based plane index within a 3-D cube HDU
  /// Registration offset o_n of ARCHITECTURE.md, px: where the star field of this frame lies beyond the
  /// linear sky-rate model (a dither, a guiding error, a re-pointing), so that frame n's IPSA shift for
  /// velocity v is round(o_n + v (t_n - t_ref)). 0 when the linear model fits (detect/registration.hpp).
  double offsetXPx = 0.0;
  double offsetYPx = 0.0;
};

/// A frame's registration offset (FrameInfo::offsetXPx, offsetYPx), px.
struct PixelOffset {
  double x = 0.0;
  double y = 0.0;
};

class FrameCube {
 public:
  FrameCube() = default;
  /// Allocates `frames` zeroed frames of width x height. Throws st::InputError for non-positive sizes.
  FrameCube(int width, int height, std::size_t frames);
  /// As the constructor, but the pixels' values are unspecified: for a caller that writes every pixel before
  /// any is read (the FITS loader), which then pays no zero fill.
  static FrameCube forOverwrite(int width, int height, std::size_t frames);

  [[nodiscard]] int width() const noexcept { return m_width; }
  [[nodiscard]] int height() const noexcept { return m_height; }
  [[nodiscard]] std::size_t frameCount() const noexcept { return m_info.size(); }
  [[nodiscard]] std::size_t framePixels() const noexcept {
    return static_cast<std::size_t>(m_width) * static_cast<std::size_t>(m_height);
  }
  [[nodiscard]] bool empty() const noexcept { return m_info.empty(); }

  float* frame(std::size_t n) noexcept { return m_pixels.data() + n * framePixels(); }
  [[nodiscard]] const float* frame(std::size_t n) const noexcept {
    return m_pixels.data() + n * framePixels();
  }
  /// A copy of frame n as an Image.
  [[nodiscard]] Image frameImage(std::size_t n) const;

  PixelVector& pixels() noexcept { return m_pixels; }
  [[nodiscard]] const PixelVector& pixels() const noexcept { return m_pixels; }

  /// Per-pixel mask, same layout as pixels(); 1 = masked (BLANK, NaN, bad pixel). Empty = nothing masked.
  MaskVector& mask() noexcept { return m_mask; }
  [[nodiscard]] const MaskVector& mask() const noexcept { return m_mask; }
  [[nodiscard]] bool isMasked(std::size_t n, int x, int y) const noexcept {
    return !m_mask.empty() && m_mask[n * framePixels() + static_cast<std::size_t>(y) * m_width + x] != 0;
  }

  std::vector<FrameInfo>& info() noexcept { return m_info; }
  [[nodiscard]] const std::vector<FrameInfo>& info() const noexcept { return m_info; }

  /// Reference epoch: mean of the frame mid-times, MJD. Throws st::InputError on an empty cube.
  [[nodiscard]] double tRefMjd() const;
  /// t_n - t_ref in seconds for every frame.
  [[nodiscard]] std::vector<double> timeOffsetsS() const;
  /// Every frame's registration offset o_n (FrameInfo::offsetXPx/offsetYPx), in cube order.
  [[nodiscard]] std::vector<PixelOffset> frameOffsets() const;
  /// True when some frame has a non-zero registration offset (the search's shifts are then not monotone in
  /// time, and N_in is counted frame by frame).
  [[nodiscard]] bool hasFrameOffsets() const noexcept;
  /// Last mid-time minus first mid-time, seconds.
  [[nodiscard]] double timeSpanS() const;

  /// Header of the first frame (all cards, for provenance and for writing stacks).
  FitsHeader header;
  /// World coordinates of the first frame, when its header has a usable WCS.
  std::shared_ptr<const Wcs> wcs;
  /// Plate scale in arcsec/px: from the WCS, or given by the user. Empty when unknown.
  std::optional<double> plateScaleArcsecPerPx;
  /// Non-fatal problems met while loading (e.g. frames sorted by time), for the user to see.
  std::vector<std::string> warnings;

 private:
  struct Unwritten {};
  FrameCube(int width, int height, std::size_t frames, Unwritten);

  int m_width = 0;
  int m_height = 0;
  PixelVector m_pixels;
  MaskVector m_mask;
  std::vector<FrameInfo> m_info;
};

}  // namespace st

#pragma once
// Frame-to-frame links of the registration (core/detect/registration.cpp): each frame's star image (binned,
// clipped, edge-tapered) and the phase correlation of two of them, high-passed, with its peak's significance
// and error. Internal to core/detect.
#include <cstddef>
#include <optional>
#include <vector>

#include "st/common/frame_cube.hpp"
#include "st/detect/registration.hpp"

namespace st::detect::detail {

/// What depends only on the (binned) image size, made once per registration rather than per frame or link.
/// Edge taper (cosine over the outer band): a star entering or leaving the frame is cut by the edge, and the
/// cut is fixed on the detector; untapered, a bright star's cut pulls the correlation peak towards zero
/// shift (a drifting EMCCD field measured 0.2 px steps for 1 px ones while a 10.5 mag star entered).
/// High-pass on the r2c half spectrum (h rows of w / 2 + 1): 1 - exp(-(k s)^2 / 2), s = kHighPassPx /
/// (2 pi), so broad clipped disks of saturated stars do not dominate and blur the peak.
struct CorrelationWeights {
  std::vector<float> taperX, taperY;  ///< per column / row of the star image
  std::vector<float> highPass;        ///< per frequency of the half spectrum
};

/// Star images of the frames, computed on demand and kept (a link needs its two frames' images).
class StarImages {
 public:
  /// `gate` (may be empty) is called before a frame's pixels are read.
  explicit StarImages(const FrameCube& cube, FrameGate gate = {});
  [[nodiscard]] const CorrelationWeights& weights() const noexcept { return m_weights; }
  [[nodiscard]] int bin() const noexcept { return m_bin; }
  [[nodiscard]] int width() const noexcept { return m_w; }
  [[nodiscard]] int height() const noexcept { return m_h; }
  /// Frame n's star image (binned, clipped, tapered).
  [[nodiscard]] std::vector<float> make(std::size_t n) const;

 private:
  const FrameCube& m_cube;
  FrameGate m_gate;
  int m_bin = 1, m_w = 0, m_h = 0;
  CorrelationWeights m_weights;
};

/// The 1-sigma error (px, per axis) of a correlation step measured at peak significance `snr`: 1.5 px / SNR
/// (the scatter of links at SNR 80 on the paper's EMCCD cube: 0.016-0.02 px), inflated below SNR ~15, where
/// the peak is broad and may blend with noise peaks (links at SNR 8-12 scatter by 0.3-0.7 px there).
double linkSigmaPx(double snr);

struct Link {
  PixelOffset step;  ///< from the earlier frame to the later, full-resolution px
  double snr = 0.0;
  double sigma = 0.0;  ///< 1-sigma error of the step per axis, full-resolution px (linkSigmaPx x bin)
  bool ok = false;
};

/// The step from frame `earlier` to frame `later` by phase correlation of their star images; ok when its peak
/// significance reaches minSnr. With `guide` (full-resolution px) the peak is looked for only within
/// guideRadius of it, and one on that rim is rejected.
Link measureLink(const StarImages& images, std::size_t later, std::size_t earlier, double minSnr,
                 const std::optional<PixelOffset>& guide = std::nullopt, double guideRadius = 0.0);

/// The link of a peak measured elsewhere (RegistrationLinkPeak, unguided), as measureLink makes it.
Link linkFromPeak(const StarImages& images, const RegistrationLinkPeak& peak, double minSnr);

}  // namespace st::detect::detail

#pragma once
// Internal to st::fit: the pixels of a co-moving fit (stamps that follow the track) and the accumulation of
// the cost, J^T J and J^T r over them. Not a public header.
#include <cstddef>
#include <vector>

#include "st/common/frame_cube.hpp"
#include "st/common/image.hpp"
#include "st/fit/comoving_fit.hpp"
#include "st/fit/pixel_psf.hpp"

namespace st::fit::detail {

struct NormalEquations {
  ParamMatrix jtj = ParamMatrix::Zero();
  ParamVector jtr = ParamVector::Zero();
  double cost = 0.0;
  std::size_t pixels = 0;
};

class FitProblem {
 public:
  /// `frames`: cube frame indices; `times`: their times relative to the fit's reference time (s).
  FitProblem(const FrameCube& cube, std::vector<std::size_t> frames, std::vector<double> times,
             const psf::Moffat& psf, int halfSize);

  /// Centres every frame's stamp on the rounded track of `p`.
  void centreStamps(const FitParams& p);
  /// Largest |rounded track - stamp centre| over frames and axes (pixels).
  [[nodiscard]] int centreDrift(const FitParams& p) const;
  /// Cost, and J^T J, J^T r when `withJacobian` (r = data - model, J = d model / d params).
  [[nodiscard]] NormalEquations evaluate(const FitParams& p, bool withJacobian) const;
  /// Sum over stamp pixels of j j^T var, var = sigmaN2 + max(alpha P, 0) / gain (background plus photon
  /// noise of the source, data units^2): the middle of the sandwich covariance.
  [[nodiscard]] ParamMatrix noiseMoment(const FitParams& p, double sigmaN2, double gain) const;
  /// Linear least squares for (alpha, I0) with the track of `p` held fixed (I0 held when !fitI0).
  [[nodiscard]] FitParams linearAmplitude(const FitParams& p, bool fitI0) const;
  /// Sums over the stamps at the track of `p`: n, sum P, sum P^2, sum d, sum d P.
  struct LinearSums {
    double n = 0, sp = 0, spp = 0, sd = 0, sdp = 0;
  };
  [[nodiscard]] LinearSums linearSums(const FitParams& p) const;
  /// Data, model and residual stacks on the current stamp grid (integer-shift aligned).
  void stacks(const FitParams& p, Image& data, Image& model, Image& residual) const;
  /// Frames whose track position (pixel centre convention) lies inside the frame: the N_in of the paper's
  /// IPSA boundary rule, which is the N_f that enters detection_snr and eq:sig.
  [[nodiscard]] std::size_t framesInside(const FitParams& p) const;
  [[nodiscard]] std::size_t frameCount() const noexcept { return m_frames.size(); }
  [[nodiscard]] int halfSize() const noexcept { return m_half; }

 private:
  template <typename PixelFn>
  void forEachPixel(std::size_t k, const PixelFn& fn) const;

  const FrameCube& m_cube;
  std::vector<std::size_t> m_frames;
  std::vector<double> m_times;
  std::vector<double> m_ox, m_oy;  ///< registration offsets of m_frames (FrameInfo::offsetXPx/offsetYPx)
  std::vector<int> m_cx;
  std::vector<int> m_cy;
  psf::Moffat m_psf;
  PixelPsfTable m_table;
  int m_half;
};

}  // namespace st::fit::detail

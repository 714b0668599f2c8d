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

  /// The model subtracts what the per-pixel background `windows` took of the source
  /// (FitOptions::selfSubtraction); `tRefOffsetS` is the fit's reference time (s from the cube's t_ref),
  /// `clipLevel` the data value above which a sample was clipped out of it; `sourceInBackground` false keeps
  /// the windows for the noise correlations alone (no background terms). Before centreStamps.
  void setSelfSubtraction(const stats::PixelBackgroundWindows& windows, double tRefOffsetS, double clipLevel,
                          bool sourceInBackground);
  /// Centres every frame's stamp on the rounded track of `p` (and gathers the background terms that reach
  /// the stamps).
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
  /// Sums over the stamps at the track of `p`: n, sum E, sum E^2, sum d, sum d E (E = P less its background
  /// terms), and sum E P, sum P^2 with the source's own P.
  struct LinearSums {
    double n = 0, sp = 0, spp = 0, sd = 0, sdp = 0, sep = 0, sPP = 0;
  };
  [[nodiscard]] LinearSums linearSums(const FitParams& p) const;
  /// The same from given sums (the track of `p` held).
  [[nodiscard]] static FitParams linearAmplitude(const FitParams& p, bool fitI0, const LinearSums& l);
  [[nodiscard]] bool hasBackgroundTerms() const noexcept { return !m_terms.empty(); }
  /// sum E P / sum P^2 over the stamps at the track of `p`: the share of the source's detection SNR that a
  /// filter matched to P at the track (the search's) sees once the background terms took theirs (1 without
  /// them). Not sqrt(sum E^2 / sum P^2): the terms' negative images repeat other frames' flux and noise.
  [[nodiscard]] double snrKept(const FitParams& p) const;
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
  /// The model's PSF part at pixel (x, y) of stamp k for the track of `p`: value E = P_k - sum_g w_g P_g,
  /// the source's own P_k, and the parts of E's gradient, J = -alpha (at du, at dv, du, dv) for (vx, vy,
  /// xc, yc).
  struct ModelSample {
    double value, own, atDu, atDv, du, dv;
  };
  [[nodiscard]] ModelSample modelSample(std::size_t k, int x, int y, const FitParams& p) const noexcept;
  void gatherBackgroundTerms(const FitParams& p);
  /// One stamp pixel's sample of fit frame k: its row of J.
  struct PixelSample {
    std::size_t k;
    ParamVector j;
  };
  /// The correlation of the fit frames' background noise (noiseMoment).
  struct NoiseCorrelation {
    std::vector<std::size_t> lo, hi, pos;  ///< per fit frame: left-out range, index in the windows' frames
    std::size_t total = 0;                 ///< frames of the background
    [[nodiscard]] bool empty() const noexcept { return total == 0; }
    /// sum over the pixel's samples' pairs of K(k, k') j_k j_k'^T (reorders `list`).
    [[nodiscard]] ParamMatrix pixelMoment(std::vector<PixelSample>& list) const;
  };
  static constexpr std::size_t kNone = static_cast<std::size_t>(-1);
  [[nodiscard]] NoiseCorrelation noiseCorrelation() const;

  const FrameCube& m_cube;
  std::vector<std::size_t> m_frames;
  std::vector<double> m_times;
  std::vector<double> m_ox, m_oy;  ///< registration offsets of m_frames (FrameInfo::offsetXPx/offsetYPx)
  std::vector<int> m_cx;
  std::vector<int> m_cy;
  psf::Moffat m_psf;
  PixelPsfTable m_table;
  int m_half;

  /// One background term of a stamp: frames of its background within a FWHM / 8 of each other, at their
  /// mean time (from the fit's reference) and mean registration offset, weighted by their share.
  struct BackgroundTerm {
    double t, ox, oy, w;
  };
  const stats::PixelBackgroundWindows* m_windows = nullptr;
  bool m_termsOn = false;  ///< gather background terms (the source is in its background)
  double m_tRefOffsetS = 0.0;
  double m_clipLevel;
  double m_termReach2 = 0.0;            ///< squared distance beyond which a term's P is ignored
  std::vector<BackgroundTerm> m_terms;  ///< of every stamp, stamp k's in [m_termStart[k], [k + 1])
  std::vector<std::size_t> m_termStart;
};

}  // namespace st::fit::detail

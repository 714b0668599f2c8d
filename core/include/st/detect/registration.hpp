#pragma once
// Per-frame registration (issue 15, item 1; ARCHITECTURE.md "Registration"): where each frame's star field
// lies, so that a dithered, badly guided or re-pointed sequence is searched as well as a perfectly tracked
// one. Frame n's IPSA shift for velocity v is round(o_n + v (t_n - t_ref)), with o_n the frame's offset
// beyond the linear sky-rate model (FrameInfo::offsetXPx/offsetYPx).
//
// Measurement: each frame's star image (background-subtracted, in single-frame sigmas, clipped to
// [0, kClipSigma] and zero below kFloorSigma, masked pixels 0; binned 2x2 when the frame is wider or taller
// than 1024 px) is cross-correlated (FFT, the whole frame, so any shift up to half the frame is found) with
// its predecessor's; the peak (parabolic sub-pixel) gives the star field's step between the two. The steps
// are chained (P_0 = 0, P_n = P_{n-1} + step_n), so the field may change completely over the sequence: only
// neighbours need to share stars. A link whose peak is not significant (SNR < minPeakSnr) is retried against
// the frame before (up to 3 back); a frame no link reaches is placed at the significant links' median rate
// with a 5 px error (the anchor pass re-measures what follows it); fewer than half the links significant
// leaves the registration unmeasured.
// Model: the linear sky rate r is the median of the pairwise slopes (P_j - P_i) / (t_j - t_i) over pairs at
// most a quarter of the sequence apart (Theil-Sen, robust to dithers and to a jump), or the given rate. The
// residuals o_n = P_n - r (t_n - t_0) (so o_0 = 0: frame 0 keeps the WCS's mapping) have an rms; at most
// linearRmsPx: the linear model fits and o_n = 0 is kept; above: the per-frame residuals are used, but only
// for frames whose residual exceeds 5 sigma of their own position error (each link's error is 1.5 px / SNR
// of its peak, inflated below SNR 15, propagated along the links that placed the frame); the others keep
// o_n = 0, and with none the linear model stays. Star images are tapered at the frame edges and the
// correlation is high-pass filtered (structure wider than 12 px is left out), and the re-measurement
// against an anchor looks for its peak only near the chained estimate.
// Long sequences (more than 2 x kQuickFrames frames): first kQuickFrames evenly spaced links (frame n with
// n + 1); when at least half are significant and each significant one agrees with the linear model within
// quickTolerancePx (or 5 sigma of its own error) the linear model is kept without measuring every frame (the
// paper's scanning telescope, 1500 frames at 16.7 Hz, whose field crosses the frame three times and leaves a
// quarter of its frames with too few stars to link); when fewer than half of them are significant (frames
// too faint to follow one by one) the registration is Unmeasured at once.
// Cost: two real FFTs of a frame per link, parallel over links; memory: a frame's spectrum per link in
// flight.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "st/common/frame_cube.hpp"
#include "st/common/progress.hpp"
#include "st/common/units.hpp"

namespace st::detect {

struct RegistrationParams {
  double linearRmsPx = 0.35;      ///< residual rms (px) up to which the linear sky rate is the model
  double minPeakSnr = 8.0;        ///< correlation peak over its surface's rms for a link to count
  double quickTolerancePx = 0.6;  ///< long sequences: a sampled link agrees with the linear model
  /// Per-frame model: move every frame by the whole pixels of its offset onto frame 0's pixel grid
  /// (alignWholePixels), so that the per-pixel background, noise and static-source masks, which work at
  /// fixed pixels, see a still sky as in an undithered sequence; only the sub-pixel remainders stay offsets.
  /// Pre-processing moves the filtered (and zero-biased) frames back onto their own grids after the matched
  /// filter (restoreWholePixels), so that the search's N_in counts only the frames that saw each track
  /// position, and the filter normalises each pixel by the frames that cover it (NoiseModel::framesCovering).
  /// On by default since 2026-11-27: 5945 on the dithered Lowell crop at 0.973 of its undithered SNR (0.934
  /// without; best lattice phases); the 128 px simulated dither test 0.975 (0.997 without, whose
  /// time-averaged normalisation on detector pixels overrates partly covered pixels; 0.927 aligned before the
  /// move back and the per-pixel coverage).
  bool alignWholePixels = true;
};

struct Registration {
  enum class Model {
    Linear,      ///< the linear sky rate fits (o_n = 0)
    PerFrame,    ///< per-frame residual offsets are used
    Unmeasured,  ///< the star field could not be followed (faint frames): the linear model is kept
  };
  Model model = Model::Unmeasured;
  Velocity rate;                      ///< the linear rate r, px/s (Theil-Sen, or the given one)
  std::vector<PixelOffset> position;  ///< measured star-field position P_n relative to frame 0, px (empty
                                      ///< when not every frame was measured)
  std::vector<PixelOffset> offsets;   ///< o_n to apply (all 0 unless PerFrame), cube order
  double rmsPx = 0.0;                 ///< rms of the residuals from the linear model, px
  double maxPx = 0.0;                 ///< largest residual, px
  int linksMeasured = 0;              ///< links whose peak was significant
  int linksElsewhere = 0;             ///< sampled links a device measured (RegistrationHooks::links)
  int significantFrames = 0;          ///< frames whose offset departs from the model beyond 5 sigma of
                                      ///< its measurement (the others keep o_n = 0)
  /// Of those, frames taken for measurement outliers of a linear field and kept on the line (a few isolated
  /// frames of a long sequence: detect/registration.cpp); the model is then Linear.
  int outlierFrames = 0;
  /// The whole-pixel shifts alignWholePixels moved frame n by (its content by -alignedPx[n]), cube order;
  /// empty when no frame was moved (or restoreWholePixels moved them back).
  std::vector<std::pair<int, int>> alignedPx;
  std::string rateNote;  ///< how the rate was taken (an axis without significant drift is 0)
  std::string note;      ///< for the user: which model, with the rms
};

/// Called before frame n's pixels are read, from several threads at once: blocks until they are there (a
/// device's download of the frames still running behind, issue 16). May throw (the download failed).
using FrameGate = std::function<void(std::size_t n)>;

/// The long sequences' sampled links for a device (issue 16): each pair's two frames made into star images
/// as the CPU makes them (the sampled median and MAD of every 7th pixel, unmasked and finite; binned by
/// `bin`; in the binned image's sigma; zeroed below 2.5 and clipped at 30; tapered by taperX x taperY) and
/// cross-correlated over the whole image (width x height, the binned size) with the high-pass `highPass`
/// (on the r2c half spectrum: height rows of width / 2 + 1): the first largest value in raster order, its
/// parabolic sub-pixel vertex and its significance over the surface's mean and rms.
struct RegistrationLinkBatch {
  int bin = 1, width = 0, height = 0;
  const std::vector<float>* taperX = nullptr;  ///< width values
  const std::vector<float>* taperY = nullptr;  ///< height values
  const std::vector<float>* highPass = nullptr;
  std::vector<std::pair<std::size_t, std::size_t>> pairs;  ///< (later, earlier) frame indices of the cube
};

/// One pair's peak: the step from the earlier frame's star image to the later one's (binned px, in
/// [-width/2, width/2) and [-height/2, height/2)) and its significance; `ok` false: not made there (the CPU
/// measures that link).
struct RegistrationLinkPeak {
  double dx = 0.0, dy = 0.0, snr = 0.0;
  bool ok = false;
};

/// Measures a batch of sampled links elsewhere (a device: the transforms' floats differ from FFTW's by
/// rounding, the star images are the CPU's bit for bit); none: the CPU measures them all.
using RegistrationLinkProvider = std::function<std::optional<std::vector<RegistrationLinkPeak>>(
    const FrameCube& cube, const RegistrationLinkBatch& batch)>;

/// What a device adds to measureRegistration: the frame gate and the sampled links' provider (either may be
/// empty).
struct RegistrationHooks {
  FrameGate gate;
  RegistrationLinkProvider links;
};

/// Measures the registration of `cube` (model above). `givenRate` (px/s) replaces the Theil-Sen rate when
/// set. Frames need not be in time order (they are linked in time order). Never throws for unusable data
/// (the result says Unmeasured); throws st::Cancelled. hooks.gate, when set, is called before each frame is
/// read on the host (the long sequences' sampled links read only 2 x 64 frames, none when hooks.links
/// measures them all).
Registration measureRegistration(const FrameCube& cube, std::optional<Velocity> givenRate,
                                 const RegistrationParams& params, ProgressSink& progress,
                                 CancelToken& cancel, const RegistrationHooks& hooks = {});

/// Writes reg.offsets into the frames (FrameInfo::offsetXPx/offsetYPx); all 0 unless reg.model is PerFrame.
void applyRegistration(FrameCube& cube, const Registration& reg);

/// Per-frame model only (else nothing): moves the content of frame n by -round(o_n) (a star at p + o_n goes
/// to p + o_n - round(o_n)), the pixels it uncovers 0 and masked, and leaves the remainders
/// o_n - round(o_n) (|.| <= 0.5 px) in reg.offsets; reg.position is kept as measured. Returns the number
/// of frames moved. Throws st::Cancelled.
std::size_t alignWholePixels(FrameCube& cube, Registration& reg, CancelToken& cancel);

/// Undoes alignWholePixels on a cube derived from the aligned one (the zero-biased or the filtered frames):
/// moves frame n's content by +reg.alignedPx[n] (the pixels it uncovers 0, and masked when the cube has a
/// mask), adds the shifts back to reg.offsets and to the frames' offsets (FrameInfo), so the search's shift
/// round(o_n + v dt) falls on the same pixels. Does not clear reg.alignedPx (several cubes may be restored);
/// the caller does. Nothing when reg.alignedPx is empty. Throws st::Cancelled and st::InputError when the
/// frame counts differ.
void restoreWholePixels(FrameCube& cube, const Registration& reg, CancelToken& cancel);

/// The number of frames whose own pixel grid covers each pixel of frame 0's grid after alignWholePixels
/// (width x height, row-major): pixel q is covered by frame n when q + alignedPx[n] lies in the frame. Empty
/// when reg.alignedPx is empty.
std::vector<std::uint32_t> alignedCoverage(const Registration& reg, int width, int height);

/// The step of the star field from image `b` to image `a` (a star at p in b is at p + step in a), both
/// width x height, by FFT cross-correlation of their star images (as above); `snr` is the peak's
/// significance. For tests and for measureRegistration.
PixelOffset correlationStep(const float* a, const float* b, int width, int height, double& snr);

}  // namespace st::detect

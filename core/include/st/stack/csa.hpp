#pragma once
// Continuous-Shift-Add synthetic tracking (paper §2.2): every frame shifted by the real-valued
// Delta_n = v (t_n - t_ref) by spectral interpolation (\label{spec_interp}: the shifted image's spectrum is
// the original's times a phase linear in frequency), then summed:
//   S(x, y, v) = sum_n F_n(x + vx (t_n - t_ref), y + vy (t_n - t_ref)).
// Since the transform is linear, the phase-shifted spectra are summed and transformed back once: one
// forward r2c FFT per frame, one inverse (FFTW single precision). Each frame is zero-padded to at least
// width + max|Delta_x| + margin (and likewise in y), so a shifted frame moves into zeros instead of wrapping
// around onto the opposite edge. Frames run in parallel, each thread with its own accumulated spectrum.
// Safe to call from several threads at once (FFTW planning is serialised, plans are cached per size).
#include <vector>

#include "st/common/frame_cube.hpp"
#include "st/common/progress.hpp"
#include "st/common/units.hpp"
#include "st/stack/ipsa.hpp"

namespace st::stack {

struct CsaOptions {
  int marginPx = 8;  ///< zero padding beyond the largest shift, px (room for the interpolation kernel)
  bool measurePlans = true;  ///< FFTW_MEASURE (slower first call per size, faster after) or FFTW_ESTIMATE
};

/// The FFT size used for n: the smallest m >= n with prime factors 2, 3, 5 only and a multiple of 16 (of 2
/// below 64). FFTW on this machine: 576^2 r2c 2.0 ms, 540^2 2.6 ms, 525^2 (odd) 5.5 ms, so even sizes rich
/// in 2 win even when larger.
int fftFriendlySize(int n);

/// The CSA stack of `cube` at velocity v (px/s). nIn counts, per pixel, the frames whose sample point
/// x + round(Delta_n) is inside the frame (the IPSA rule), so S / (sigma sqrt(N_in)) means the same for both
/// stacks. Frames whose shift moves them entirely out of the image are skipped. Reports progress; throws
/// st::Cancelled, and st::InputError for an empty cube or more than 65535 frames.
StackResult stackCsa(const FrameCube& cube, Velocity v, ProgressSink& progress, CancelToken& cancel,
                     const CsaOptions& options = {});

/// As above with precomputed t_n - t_ref (seconds, one per frame).
StackResult stackCsa(const FrameCube& cube, const std::vector<double>& offsetsS, Velocity v,
                     ProgressSink& progress, CancelToken& cancel, const CsaOptions& options = {});

/// Shifts one image by spectral interpolation: out(x, y) = in(x + dx, y + dy), zero outside the image
/// (padded as for stackCsa). For sub-pixel resampling elsewhere (e.g. a refined PSF of a tracked object).
Image shiftImage(const Image& in, double dx, double dy, const CsaOptions& options = {});

}  // namespace st::stack

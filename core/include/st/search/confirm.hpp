#pragma once
// Confirmation of a candidate in a second observation (paper §4.5, §5.1: the faint asteroid found at SNR ~15
// was confirmed in a second 30 s cube taken 77 minutes later). The candidate's position at t_ref1 and its
// velocity predict where it is at t_ref2; only a small window of (x, y, v) around the prediction is
// searched, so the confirmation false-alarm probability (the equation after Prob_false) counts the window's
// trials dN_x dN_y dN_vx dN_vy, not the whole search's.
#include <optional>

#include "st/common/progress.hpp"
#include "st/search/types.hpp"

namespace st::search {

struct ConfirmRequest {
  double x = 0.0;                     ///< candidate column at t_ref1 (0-based, pixels of the first cube)
  double y = 0.0;                     ///< candidate row at t_ref1
  Velocity v;                         ///< candidate velocity, px/s
  double tRef1Mjd = 0.0;              ///< reference epoch of the first cube
  double sigmaPosPx = 0.5;            ///< 1-sigma position uncertainty at t_ref1 (grid search: ~0.5 px)
  std::optional<double> sigmaVelPxS;  ///< 1-sigma velocity uncertainty; default: one grid step (the
                                      ///< search peak is about a step wide; a co-moving fit does better)
  double gridStepPxS = 0.0;  ///< velocity step of the first search; also the window's step (required)
  double offsetX = 0.0;      ///< column of the second cube's pixel (0, 0) in the first cube's pixels
  double offsetY = 0.0;      ///< same for rows (0 when both cubes share the pointing)
  double nSigma = 3.0;       ///< window half-widths in sigmas (position and velocity)
  double targetFap = 0.01;   ///< confirmation FAP that sets the threshold over the window's trials
};

struct ConfirmResult {
  double dtS = 0.0;    ///< t_ref2 - t_ref1, seconds
  double predX = 0.0;  ///< predicted column at t_ref2, second cube's pixels
  double predY = 0.0;
  double sigmaPosPx = 0.0;  ///< predicted 1-sigma position uncertainty at t_ref2: sigma_pos + sigma_v |dt|
  int x0 = 0, y0 = 0;       ///< window searched: columns [x0, x0 + width), rows [y0, y0 + height)
  int width = 0, height = 0;
  VelocityGrid grid;          ///< velocities searched (centred on the candidate's velocity)
  TrialCounts trials;         ///< dN_x, dN_y, dN_vx, dN_vy of the window
  double snrThreshold = 0.0;  ///< from targetFap over the window's trials
  Candidate best;             ///< the best cell in the window (x, y at t_ref2)
  double snr = 0.0;           ///< its SNR
  double fap = 1.0;           ///< confirmation false-alarm probability at that SNR
  bool confirmed = false;     ///< snr > snrThreshold
  double tRef2Mjd = 0.0;
};

/// Searches the window around the prediction in `cube2` with the exact CPU kernel. Throws st::InputError
/// when the request is malformed (no grid step, negative sigmas) or the window lies outside cube2, and
/// st::Cancelled.
ConfirmResult confirmCandidate(const FilteredCube& cube2, const ConfirmRequest& request,
                               ProgressSink& progress, CancelToken& cancel);

}  // namespace st::search

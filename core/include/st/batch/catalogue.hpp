#pragma once
// The merged catalogue of a batch (issue 17): every observation's candidates in one list, the same object
// seen by overlapping cubes of one group kept once, and the observations that failed or were not done.
#include <array>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace st::batch {

/// How one observation ended, as the catalogue needs it.
struct Outcome {
  std::string name;
  std::string group;  ///< empty: its own group
  std::vector<std::string> inputs;
  enum class Status { Done, Failed, NotDone } status = Status::NotDone;
  std::string error;      ///< Failed: what went wrong; NotDone: why (e.g. its worker died)
  nlohmann::json result;  ///< Done: the search result (candidates.json), candidates with "fit"
};

struct MatchParams {
  /// Two detections are one object when, at the epoch of the brighter one, their positions differ by at
  /// most this (px) plus the velocity uncertainty (one grid step) times the time between the epochs...
  double positionTolPx = 3.0;
  /// ...and their velocities by at most this many grid steps (the coarser grid of the two) per component.
  double velocityTolSteps = 2.0;
  /// Detections from observations that share frames (overlapping cubes: both results carry t_first_mjd and
  /// t_last_mjd) are instead one object when their tracks stay within this (px) of each other at the start,
  /// middle and end of the shared frames (about two PSF FWHM of the paper's camera); this also joins a
  /// partial detection at a cube's edge, whose velocity is off, to the object's full track.
  double overlapTolPx = 5.0;
};

/// The position and velocity a catalogue entry quotes for a candidate of `result`: the fit's when it
/// converged, else the search cell's. Returns {x, y, vx, vy} (px at result's t_ref, px/s).
std::array<double, 4> bestState(const nlohmann::json& candidate);

/// The catalogue: {"observations": [names in list order], "candidates": [...], "errors": [...],
/// "not_done": [...]}. A candidate entry: observation, t_ref_mjd, x, y, vx_px_s, vy_px_s (search cell),
/// snr, n_frames, fap, flags, the sky rate/PA when known, "fit" (when fitted) and "seen_in" (every
/// observation of its group that saw the same object: observation, x, y, snr; an entry is a single-linkage
/// cluster of matching detections, never two of one observation), ordered by observation then
/// SNR. An error entry: observation, inputs, error. A not_done entry: observation, reason. Deterministic:
/// the same outcomes give the same JSON, whatever order they finished in.
nlohmann::json mergeCatalogue(const std::vector<Outcome>& outcomes, const MatchParams& match = {});

}  // namespace st::batch

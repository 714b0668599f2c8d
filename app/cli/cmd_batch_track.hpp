#pragma once
// The full-track SNR of a catalogue entry whose object crossed several cubes of one night (issue 17): the
// co-moving fit re-measured over the union of the cubes its track crosses, on rank 0 after the merge.
#include <vector>

#include <nlohmann/json.hpp>

#include "batch_runner.hpp"
#include "st/batch/catalogue.hpp"
#include "st/batch/observation_list.hpp"

namespace st::app {

struct TrackSettings {
  /// A track whose cubes hold more than this many pixels x frames (millions) is not re-measured (memory:
  /// about 16 bytes per pixel and frame while pre-processing). Default: two 1500-frame cubes of 512^2.
  double maxMegaVoxels = 800.0;
};

/// For every candidate of `catalogue` (mergeCatalogue's) from an observation of a group of two or more
/// (a night cut with --split, or a manifest's group): the interval during which its track (the fit's state
/// when converged, else the search cell's) lies inside the frame, and the group's observations whose frames
/// fall in it. When that is one observation the entry's own fit SNR is the track's; when several, their
/// frames are loaded together, pre-processed as one cube and the co-moving fit is run there from the
/// entry's state. Adds "track": {"snr", "method", "observations", "frames", "t_ref_mjd", "status", "fit"}
/// and "track_snr" (null when not measured, with "track"/"reason"). Never throws for one entry: a failure
/// is recorded in its "track". `outcomes` in the order of `observations`.
void addTrackSnr(nlohmann::json& catalogue, const std::vector<batch::Observation>& observations,
                 const std::vector<batch::Outcome>& outcomes, const BatchSettings& settings,
                 const TrackSettings& track = {});

}  // namespace st::app

#pragma once
// The velocity search as one plain function (for the demo, the CLI and the GUI): grid from a GridSpec,
// then backend.search(). Also the validation every backend applies to its inputs.
#include <string>
#include <vector>

#include "st/search/candidates.hpp"
#include "st/search/types.hpp"
#include "st/search/velocity_grid.hpp"

namespace st::search {

struct SearchRequest {
  GridSpec grid;        ///< range, centre (default: the cube's sky rate), spacing
  SearchParams params;  ///< threshold (SNR or target FAP), caps
};

/// Builds the grid for `cube` and runs `backend` over it. Throws st::InputError for bad input (see
/// validateSearchInput, makeVelocityGrid), st::Cancelled when cancelled.
SearchResult runSearch(SearchBackend& backend, const FilteredCube& cube, const SearchRequest& request,
                       ProgressSink& progress, CancelToken& cancel);

/// Throws st::InputError naming the value at fault unless: at least 2 frames, a positive time span,
/// sigma_F > 0 and finite, a non-empty grid with a positive finite step, minFrameFraction in [0, 1],
/// maxCandidates >= 1, and a threshold that is finite (or a target FAP in (0, trials/2]).
void validateSearchInput(const FilteredCube& cube, const VelocityGrid& grid, const SearchParams& params);

/// The SNR threshold a search uses: params.snrThreshold, or the inverse of Prob_false for
/// params.targetFap with `trials` (st::stats::snrThresholdForFap).
double effectiveThreshold(const SearchParams& params, const TrialCounts& trials);

/// N_in below this is ignored: ceil(minFrameFraction x frames), at least 1.
int minFramesFor(const SearchParams& params, std::size_t frames);

/// The most frames (of those at `timesS`, any order) that a linear track at velocity v (px/s on the detector)
/// can spend inside a width x height px frame: those within the longest window of length
/// min(width / |vx|, height / |vy|). All of them for a track slow enough to stay in for the span.
int maxFramesInside(const std::vector<double>& timesS, int width, int height, Velocity v);

/// N_in below this is ignored, for a search of `grid` over frames at `timesS` of width x height px:
/// ceil(minFrameFraction x the fewest frames that a track of any grid velocity can spend inside the frame
/// (maxFramesInside at the grid's corners)), at least 1. A track that crosses the frame in less than the
/// span can never be seen in every frame: with a fraction of all frames, the paper's 1500-frame observation
/// (stars drifting 16.4 px/s across 512 px: a mover is inside for ~520 of the 1500 frames against a minimum
/// of 750) could find nothing. Equal to minFramesFor(params, frames) where every track can stay inside.
int minFramesFor(const SearchParams& params, const std::vector<double>& timesS, int width, int height,
                 const VelocityGrid& grid);

/// Validates the input (validateSearchInput) and returns a result with everything known before the search:
/// grid, trial counts, threshold, minimum frames, t_ref, backend and method names.
SearchResult startSearchResult(const FilteredCube& cube, const VelocityGrid& grid, const SearchParams& params,
                               std::string backend, SearchMethod method);

/// Sorts `hits` by decreasing SNR (ties: increasing y, x, ivy, ivx, so every backend keeps the same cells
/// and picks the same representative cell), keeps at most params.maxCandidates and clusters them into
/// result.candidates (clusterCells with the cube's PSF FWHM and result.trials), then merges the sidelobes of
/// bright candidates into them (sidelobes.hpp; result.sidelobesMerged counts them), and sets aside into
/// result.staticSources the candidates within the static-rate limit of the cube's sky rate (types.hpp).
void setCandidates(SearchResult& result, std::vector<CellHit> hits, const FilteredCube& cube,
                   const SearchParams& params);
/// The same with the cube's properties given (an out-of-core search holds no whole cube): PSF FWHM, the
/// frames' t - t_ref (s), the whole image's size, the frames' registration offsets (empty = all 0) and the
/// stars' motion, px/s.
void setCandidates(SearchResult& result, std::vector<CellHit> hits, double psfFwhmPx,
                   const std::vector<double>& dtS, int width, int height, const SearchParams& params,
                   const std::vector<PixelOffset>& offsets, Velocity skyRate);

/// The time (s) between the first and the last frame in which candidate c's track (its cell's samples:
/// ipsaShift of its grid velocity with the frame's offset) lies inside the image; 0 when in at most one.
double trackSpanS(const Candidate& c, const TrackFrames& frames);

/// Moves the candidates within the static-rate limit of `skyRate` from result.candidates to the end of
/// result.staticSources, in their order. The limit is staticRateLimitPxS of the PSF FWHM and the candidate's
/// own span inside the image (trackSpanS; the whole span of frames.dtS when that is 0): a source that the
/// field's drift carries across the image moves less than one FWHM against the stars over the frames that
/// hold it, and is as static there as one that stays in for the whole span (simulator seed 66's partial-span
/// star, 0.14 px/s off the sky rate against 0.13 px/s over the whole span).
void setAsideStaticSources(SearchResult& result, double psfFwhmPx, const TrackFrames& frames,
                           Velocity skyRate);

}  // namespace st::search

#pragma once
// Search results as JSON and CSV (ARCHITECTURE.md: units in the keys). Shared by `synthtrack-cli search`,
// the demo and the GUI's export, so every output names the same quantities the same way.
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "st/search/types.hpp"

namespace st::report {

/// One candidate: x, y (0-based, at t_ref), vx_px_s, vy_px_s (in the frames), snr, n_frames, fap, sum,
/// cluster_cells, ivx, ivy; and, when a plate scale or WCS is known, rate_deg_day and pa_deg of the motion
/// on the sky, i.e. of v - skyRate (the stars' motion in the frames is taken out: for a scanning telescope
/// the frame velocity is mostly the scan); and "flags": "at_sky_rate" when v is within one grid step of the
/// sky rate (a static source left by pre-processing), "partial" when the track leaves the frame, and
/// "crosses_brighter" when `crossingBrighter` (candidate::crossesBrighter of the search's list).
nlohmann::json candidateToJson(const search::FilteredCube& cube, const search::VelocityGrid& grid,
                               const search::Candidate& candidate, bool crossingBrighter = false);

/// The whole result: inputs, backend, method ("exact" or "tree") and method_reason (why: "requested" or
/// "auto: ...", method_choice.hpp), t_ref (MJD), frames, sigma_F, PSF FWHM, sky rate, grid, trial counts,
/// threshold, cells above threshold, minimum frames, elapsed time and the candidates.
nlohmann::json searchResultToJson(const search::FilteredCube& cube, const search::SearchResult& result,
                                  const std::vector<std::string>& inputs);

/// The inverse of candidateToJson(): x, y, vx_px_s, vy_px_s, snr, n_frames, fap, sum, cluster_cells, ivx, ivy
/// (the derived rate_deg_day, pa_deg and flags are ignored). Exact: every number is written with enough
/// digits to read back the same double. Throws st::InputError naming the missing or mistyped key.
[[nodiscard]] search::Candidate candidateFromJson(const nlohmann::json& json);

/// The velocity map as JSON: nvx, nvy and the arrays max_snr, arg_x, arg_y (row-major, iy * nvx + ix).
/// Non-finite SNRs are written as null and read back as NaN (the CPU backends never produce them).
[[nodiscard]] nlohmann::json velocityMapToJson(const search::VelocityMap& map);
/// Throws st::InputError naming the key at fault, or when the array sizes are not nvx * nvy.
[[nodiscard]] search::VelocityMap velocityMapFromJson(const nlohmann::json& json);

/// The inverse of searchResultToJson() (plus a "velocity_map" member when present, see velocityMapToJson):
/// grid, trials, snr_threshold, t_ref_mjd, backend, method, method_reason, elapsed_s, cells_above_threshold,
/// min_frames and the candidates (an absent "candidates" gives none; an absent velocity map an empty one).
/// Round trip exact. Throws st::InputError naming the key at fault.
[[nodiscard]] search::SearchResult searchResultFromJson(const nlohmann::json& json);

/// Writes the candidates of a searchResultToJson() object as CSV (one header line; empty fields where a
/// quantity is unknown; the last two columns, method and method_reason, repeat the run's on every row, the
/// reason quoted). Throws st::InputError naming the path when it cannot be written.
void writeCandidatesCsv(const std::string& path, const nlohmann::json& result);

/// Writes JSON atomically (temporary file in the same folder + rename), pretty-printed.
void writeJsonFile(const std::string& path, const nlohmann::json& json);

}  // namespace st::report

#pragma once
// The candidate record (st::candidate) as JSON, for the writers that need text: the candidates file
// (`synthtrack-cli search --json`, the demo's candidates.json, the GUI's export: flat keys, units in the
// names, what `synthtrack-cli report` and the batch catalogue read) and the session file (session.cpp: the
// same keys, the fit's uncertainties, segment check and sky position as nested objects since format 2).
// Readers take every key as optional (an older writer may lack one) and throw st::InputError naming `where`
// and the key when a value has the wrong type.
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "st/candidate/candidate_measurement.hpp"

namespace st::report {

/// x, y, vx_px_s, vy_px_s, snr (required on reading), n_frames, fap, sum, cluster_cells, ivx, ivy, flags, rate_deg_day, pa_deg.
[[nodiscard]] nlohmann::json toJson(const candidate::SearchMeasurement& search);
[[nodiscard]] candidate::SearchMeasurement searchMeasurementFromJson(const nlohmann::json& json,
                                                                     const std::string& where);

/// The flat fit object of the candidates file: status, message, iterations, x, y, vx_px_s, vy_px_s,
/// sigma_x_px, sigma_y_px, sigma_vx_px_s, sigma_vy_px_s, sigma_pos_paper_px, sigma_vel_paper_px_s,
/// photons_per_frame, snr; segments_flagged, segment_reasons, segment_snr, position_segments,
/// segment_positions (with a segment check; each {segment, mjd_utc, t_offset_s, x, y, sigma_x_px, sigma_y_px,
/// snr, and ra_deg, dec_deg, sigma_ra_arcsec, sigma_dec_arcsec with a sky position}); ra_deg, dec_deg,
/// rate_deg_day, rate_arcsec_min, pa_deg (with a sky position); t_ref_mjd, sigma_ra_arcsec, sigma_dec_arcsec,
/// mag, band when set. Also the layout of a session file of format 1.
[[nodiscard]] nlohmann::json toFlatJson(const candidate::FitSummary& fit);
[[nodiscard]] candidate::FitSummary fitFromFlatJson(const nlohmann::json& json, const std::string& where);

/// The fit of a session file (format 2): the flat keys above without the groups, plus "sigma" {x_px, y_px,
/// vx_px_s, vy_px_s, pos_paper_px, vel_paper_px_s}, "segments" {flagged, reasons, snr, positions} and "sky"
/// {ra_deg, dec_deg, rate_deg_day, rate_arcsec_min, pa_deg}.
[[nodiscard]] nlohmann::json toNestedJson(const candidate::FitSummary& fit);
[[nodiscard]] candidate::FitSummary fitFromNestedJson(const nlohmann::json& json, const std::string& where);

/// kind, triggered, value, evidence (vet::toJson) and back.
[[nodiscard]] nlohmann::json toJson(const std::vector<vet::ArtifactFlag>& flags);
[[nodiscard]] std::vector<vet::ArtifactFlag> artifactsFromJson(const nlohmann::json& json,
                                                               const std::string& where);

/// The candidates file's object of one candidate: the search keys, "fit" (flat, when there is one), "label",
/// "reason", "note" and "artifacts".
[[nodiscard]] nlohmann::json toCandidatesFileJson(const candidate::CandidateMeasurement& c);
/// A record from a candidates-file object (the search keys, with "fit", "label", "reason", "note",
/// "artifacts" when present).
[[nodiscard]] candidate::CandidateMeasurement fromCandidatesFileJson(const nlohmann::json& json,
                                                                     const std::string& where);

}  // namespace st::report

#pragma once
// The report bundle of a session (issue 18 §2): the one function behind the GUI's Export dialog and
// `synthtrack-cli report`, so both write byte-identical files for the same session. Candidates as JSON (the
// search-result format `synthtrack-cli report` reads, each candidate with its fit, label, reason, note and
// artifact flags) and CSV (one row per candidate with its vetting state); DS9 regions (report::regionMarks,
// in the WCS's sky frame moved to t_ref, image coordinates otherwise); FITS stacks tracking the sky and the
// object (report::writeStackFits: WCS at t_ref and provenance); ADES PSV / XML and MPC 80-column astrometry of
// the candidates labelled real only (report::realDetections), with a warning for every detection below the
// safe SNR. No toolkit: runs on a worker thread.
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "st/astro/astrometry.hpp"
#include "st/common/frame_cube.hpp"
#include "st/common/progress.hpp"
#include "st/report/mpc_submission.hpp"
#include "st/session/session.hpp"

namespace st::report {

/// The files of a bundle, each written when the request names a path for it.
enum class ReportFile { CandidatesJson, CandidatesCsv, Ds9, AdesPsv, AdesXml, Mpc80 };

/// Which candidates get FITS stacks.
enum class StackChoice { Real, Selected, All };

/// Where the DS9 regions are placed: pixel -> sky at t_ref (empty: image coordinates), its DS9 frame name,
/// and the observation's span relative to t_ref (s) for the track lines (none when end <= start).
struct RegionContext {
  astro::PixelToSky toSky;
  std::string frame = "image coordinates";
  double trackStartS = 0.0, trackEndS = 0.0;
};

struct ReportRequest {
  session::Session session;
  std::map<ReportFile, std::string> files;  ///< path of each file to write
  RegionContext regions;
  report::SubmissionSettings submission;
  /// FITS stacks: written as stacksStem + "_cNNN_sky.fits" / "_cNNN_object.fits" (the object only with
  /// stacksObjectOnly: stacksStem + "NNN.fits") when stacksStem is set; they need `raw`.
  std::string stacksStem;
  bool stacksObjectOnly = false;
  StackChoice stackChoice = StackChoice::Real;
  std::optional<int> selected;           ///< 0-based, for StackChoice::Selected
  std::shared_ptr<const FrameCube> raw;  ///< the observation's frames (stacks only)
  /// The registration offsets of `raw`'s frames (FrameInfo::offsetXPx/offsetYPx), one per frame, when `raw`
  /// was loaded without them (the GUI's loaded frames; its prepared frames hold them); empty: raw's own.
  /// The stacks shift by them, and their WCS and the DS9 regions map through the first one.
  std::vector<PixelOffset> frameOffsets;
};

struct ReportOutcome {
  std::vector<std::string> written;   ///< paths, in the order written
  std::vector<std::string> warnings;  ///< low SNR, real candidates without a sky position, ...
  std::size_t detections = 0;         ///< astrometric detections (positions) in the submission files
  std::size_t objects = 0;            ///< the objects (trkSubs) they are of: a tracklet is several positions
  /// Submission files asked for and not written: with no detection (no candidate labelled real with a sky
  /// position) an ADES or 80-column file would be an empty submission, which the MPC's schema rejects.
  std::vector<std::string> notWritten;
};

/// The GUI's file names in `folder`: baseName + "_candidates.json", "_candidates.csv", ".reg", ".psv",
/// ".xml", "_mpc.txt".
[[nodiscard]] std::string defaultFileName(const std::string& folder, const std::string& baseName, ReportFile file);

/// The regions' placement from the observation's frames: their WCS (ds9SkyFrame, skyMappingAtTRef with the
/// session's sky rate, the first frame's epoch and registration offset, `frameOffsets`' first when given)
/// and time span; image coordinates without a WCS.
[[nodiscard]] RegionContext regionContext(const FrameCube* raw, const session::Session& session,
                                          const std::vector<PixelOffset>& frameOffsets = {});

/// Writes the requested files (folders are created). Throws st::InputError / st::FitsError naming the path at
/// fault, and, before writing anything, st::InputError listing report::submissionProblems() when ADES or
/// MPC output is asked for with settings that would not make a valid file; polls `cancel` between files and
/// reports progress per file.
ReportOutcome writeReports(const ReportRequest& request, ProgressSink& progress, CancelToken& cancel);

/// The candidates JSON: session.search (without the velocity map) with "inputs" and "candidates" = each
/// candidate's report::toCandidatesFileJson. session::fromSearchJson() reads it back.
[[nodiscard]] nlohmann::json candidatesJson(const session::Session& session);

/// The vetted CSV: number (1-based), label, reason, note, x, y, vx_px_s, vy_px_s, snr, n_frames, fap,
/// rate_deg_day, pa_deg, flags, then the accepted fit's x, y, vx_px_s, vy_px_s, snr, ra_deg, dec_deg (empty
/// when unknown). Text fields are quoted when they hold a comma, quote or newline (RFC 4180).
[[nodiscard]] std::string candidatesCsv(const session::Session& session);

/// Warnings for the detections of the candidates labelled real (realDetections with the settings' positions)
/// below the settings' safe SNR, and for real ones not reported or reported with one position, as the dialog
/// shows them before anything is written.
[[nodiscard]] std::vector<std::string> submissionWarnings(const session::Session& session,
                                                          const SubmissionSettings& settings);

}  // namespace st::report

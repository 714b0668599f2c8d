#pragma once
// The reports of the GUI's Export menu, written from a session (ui/session_snapshot.hpp makeSession, the
// same record the session file keeps) by the core's writers: candidates as JSON (the search-result format
// `synthtrack-cli report` reads, each candidate with its fit, label, reason, note and artifact flags) and
// CSV (one row per candidate with its vetting state); DS9 regions (report::regionMarks, fk5 through the
// observation's WCS moved to t_ref, image coordinates otherwise); FITS stacks tracking the sky and tracking
// the object for chosen candidates (report::writeStackFits: WCS at t_ref and provenance); ADES PSV and MPC
// 80-column astrometry of the candidates labelled real only (report::realDetections), with a warning for
// every detection below the safe SNR. No Qt widgets: runs on a worker thread.
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "st/common/frame_cube.hpp"
#include "st/common/progress.hpp"
#include "st/report/mpc_submission.hpp"
#include "st/session/session.hpp"

namespace st::ui {

/// Which candidates get FITS stacks.
enum class StackChoice { Real, Selected, All };

struct ReportRequest {
  session::Session session;              ///< makeSession() of the GUI's state
  std::shared_ptr<const FrameCube> raw;  ///< the observation's frames: stacks and the WCS
  std::string folder;                    ///< output folder (created when missing)
  std::string baseName = "synthtrack";   ///< files are folder/baseName + suffix
  bool candidatesJson = true;            ///< baseName_candidates.json
  bool candidatesCsv = true;             ///< baseName_candidates.csv
  bool ds9 = true;                       ///< baseName.reg
  bool stacks = false;                   ///< baseName_cNNN_sky.fits and baseName_cNNN_object.fits
  bool ades = false;                     ///< baseName.psv
  bool mpc = false;                      ///< baseName_mpc.txt
  StackChoice stackChoice = StackChoice::Real;
  std::optional<int> selected;  ///< 0-based, for StackChoice::Selected
  report::SubmissionSettings submission;
};

struct ReportOutcome {
  std::vector<std::string> written;   ///< paths, in the order written
  std::vector<std::string> warnings;  ///< low SNR, real candidates without a sky position, ...
};

/// Writes the requested reports. Throws st::InputError / st::FitsError naming the path at fault, and, before
/// writing anything, st::InputError listing report::submissionProblems() when ADES or MPC output is asked for
/// with settings that would not make a valid file; polls `cancel` between files and reports progress per
/// file.
ReportOutcome writeReports(const ReportRequest& request, ProgressSink& progress, CancelToken& cancel);

/// The candidates JSON: session.search with "candidates" = each candidate object plus "fit" (when
/// accepted), "label", "reason", "note" and "artifacts". session::fromSearchJson() reads it back.
[[nodiscard]] nlohmann::json candidatesJson(const session::Session& session);

/// The vetted CSV: number (1-based), label, reason, note, x, y, vx_px_s, vy_px_s, snr, n_frames, fap,
/// rate_deg_day, pa_deg, flags, then the accepted fit's x, y, vx_px_s, vy_px_s, snr, ra_deg, dec_deg (empty
/// when unknown). Text fields are quoted when they hold a comma, quote or newline (RFC 4180).
[[nodiscard]] std::string candidatesCsv(const session::Session& session);

/// Warnings for the candidates labelled real below `safeSnr` (and real ones without a sky position), as the
/// dialog shows them before anything is written.
[[nodiscard]] std::vector<std::string> submissionWarnings(const session::Session& session, double safeSnr);

}  // namespace st::ui

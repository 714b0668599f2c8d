#pragma once
// What an astrometry submission to the Minor Planet Center says about the observation beside the positions:
// station, people, telescope, reference catalogue. One typed record, shared by the CLI (`synthtrack-cli
// report`, kept in the session's settings) and the GUI's report dialog (kept in QSettings and the session),
// with its JSON form and the check of what a valid file needs (ADES 2022 submit.xsd: observatory mpcCode,
// submitter, measurers, telescope design/aperture/detector, astCat on every optical observation; MPC1992:
// a 3-character station code and the catalogue code of column 72).
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace st::report {

/// Which positions of an object labelled real a submission gives. The MPC links a new object from a
/// tracklet of two or more positions at different times: Segments gives one per segment of the fit's segment
/// check (each segment's own fit, velocity held, at the mean time of its frames: K = 4 positions at SNR ~ the
/// whole fit's / 2); Fit gives the whole co-moving fit's one position at t_ref (the most precise, but alone).
enum class TrackletPositions { Segments, Fit };
/// "segments", "fit".
[[nodiscard]] const char* toString(TrackletPositions positions) noexcept;
/// Throws st::InputError naming the text when it is neither key.
[[nodiscard]] TrackletPositions trackletPositionsFromString(const std::string& text);

struct SubmissionSettings {
  std::string stationCode;                    ///< MPC observatory code, 3 characters (required)
  std::string observers;                      ///< observer name(s), comma-separated ("A. Smith, B. Jones")
  std::string measurer;                       ///< measurer name; default: the first observer
  std::string submitter;                      ///< default: the measurer
  std::string contactEmail;                   ///< where the MPC sends its acknowledgment (80-column AC2 line)
  std::string telescopeDesign = "reflector";  ///< ADES telescope design (reflector, refractor, Schmidt, ...)
  double apertureM = 0.0;        ///< telescope aperture, metres; ADES requires it (0 = not given)
  std::string detector = "CCD";  ///< ADES telescope detector and observation mode: CCD or CMO (CMOS)
  std::string
      astCat;  ///< reference catalogue of the WCS solution (ADES astCat, e.g. "Gaia3"); ADES requires it
  /// The reference catalogue by its 80-column code (star_catalogues.hpp), for the NET line; ' ' = astCat's.
  /// Column 72 itself is left blank in a submission (the MPC fills it).
  char mpcCatalogCode = ' ';
  double safeSnr = 7.0;  ///< below this SNR a line gets a warning (paper §4.4 threshold)
  TrackletPositions positions =
      TrackletPositions::Segments;  ///< positions per object (report::realDetections)
};

enum class SubmissionFormat { Ades, Mpc80 };

/// A value a valid file needs that the settings lack or hold malformed. `key` is the value's key in the
/// settings JSON (toJson below: station, observers, measurer, submitter, contact_email, telescope_design,
/// aperture_m, detector, ast_cat, mpc_catalog_code), for a front end to name its own option or field.
struct SettingsProblem {
  std::string key;
  std::string message;
};

/// Every problem that would make a file of `format` invalid (empty when none). ADES: station code (3
/// letters/digits), a measurer (given or the first observer), names of at most 100 characters, telescope
/// design and detector (1-25 characters; the detector also the observation mode, so one of the MPC's modes),
/// aperture > 0 and below 1000 m, astCat (1-8 of [.A-Za-z0-9_]). MPC 80-column: station code, and a
/// catalogue for the NET line (astCat, or a code of the MPC's list).
[[nodiscard]] std::vector<SettingsProblem> submissionProblems(const SubmissionSettings& settings,
                                                              SubmissionFormat format);
/// The problems as one sentence: "ADES needs: the telescope aperture (...); astCat (...)".
[[nodiscard]] std::string problemsText(const std::vector<SettingsProblem>& problems, SubmissionFormat format);

/// The measurer: the given one, else the first observer (trimmed); may be empty.
[[nodiscard]] std::string measurerOf(const SubmissionSettings& settings);
/// The observers, split at commas and trimmed, empty names dropped.
[[nodiscard]] std::vector<std::string> observerNames(const SubmissionSettings& settings);
/// The catalogue's 80-column code: the given one, else astCat's (' ' when neither).
[[nodiscard]] char resolvedCatalogueCode(const SubmissionSettings& settings);
/// The NET line's catalogue: the MPC's name for the resolved code (e.g. "Gaia-DR3"), else astCat as given
/// (empty when neither).
[[nodiscard]] std::string netCatalogueName(const SubmissionSettings& settings);

/// The settings as kept in a session's settings and in the GUI's QSettings: station, observers, measurer,
/// submitter, contact_email, telescope_design, aperture_m, detector, ast_cat, mpc_catalog_code (one
/// character, " " = from astCat), safe_snr, positions ("segments" or "fit").
[[nodiscard]] nlohmann::json toJson(const SubmissionSettings& settings);
/// The inverse; missing, mistyped or unknown values keep the defaults of SubmissionSettings.
[[nodiscard]] SubmissionSettings submissionFromJson(const nlohmann::json& json);

}  // namespace st::report

#pragma once
// Astrometry for the Minor Planet Center: ADES PSV (pipe-separated values, ADES version 2017) and the
// MPC1992 80-column format, for detections a person labelled real (issue 8). Both are fixed by the MPC:
//   80-column: cols 1-5 number (blank), 6-12 provisional/temporary designation, 13 discovery asterisk,
//   14 note 1, 15 note 2 ('C' CCD, 'B' CMOS), 16-32 date "YYYY MM DD.dddddd" (UTC), 33-44 RA
//   "HH MM SS.sss", 45-56 Dec "sDD MM SS.ss", 57-65 blank, 66-70 magnitude ("22.9 "), 71 band,
//   72 astrometric catalogue code, 73-77 blank, 78-80 observatory code.
//   ADES PSV: '#'/'!' header blocks (observatory mpcCode, submitter, observers, measurers, telescope), one
//   line of field names, then one '|'-separated line per observation; obsTime ISO 8601 UTC with 'Z', ra and
//   dec in decimal degrees, rmsRA (RA cos Dec) and rmsDec in arcsec, logSNR = log10(SNR).
// Shift-and-stack users are asked by the MPC not to submit detections pulled out of noise: every line below
// `safeSnr` adds a warning (the CLI prints them on stderr, the GUI shows them).
#include <optional>
#include <string>
#include <vector>

namespace st::report {

struct SubmissionSettings {
  std::string stationCode;  ///< MPC observatory code, 3 characters (required)
  std::string observers;    ///< observer name(s), comma-separated ("A. Smith, B. Jones")
  std::string measurer;     ///< measurer name; default: the first observer
  std::string submitter;    ///< default: the measurer
  std::string telescopeDesign = "reflector";
  double apertureM = 0.0;        ///< telescope aperture, metres (0 = not written)
  std::string detector = "CCD";  ///< ADES detector/mode: CCD or CMO
  std::string astCat;  ///< reference catalogue of the WCS solution (ADES astCat, e.g. "Gaia3"); required
  char mpcCatalogCode = ' ';  ///< column 72 of the 80-column format (e.g. 'V' Gaia DR2, 'W' Gaia DR3)
  double safeSnr = 7.0;       ///< below this SNR a line gets a warning (paper §4.4 threshold)
};

/// One measured position of a detection labelled real.
struct AstrometricDetection {
  std::string trkSub;   ///< observer's designation, up to 7 characters for the 80-column format (ADES: 8)
  double mjdUtc = 0.0;  ///< epoch of the position (t_ref, the mean of the frames' mid-times)
  double raDeg = 0.0, decDeg = 0.0;     ///< ICRS
  std::optional<double> sigmaRaArcsec;  ///< RA cos Dec
  std::optional<double> sigmaDecArcsec;
  std::optional<double> mag;
  std::string band = "G";
  double snr = 0.0;
};

struct SubmissionText {
  std::string text;
  std::vector<std::string> warnings;  ///< low SNR, missing catalogue, truncated designation, ...
};

/// One 80-column line (exactly 80 characters, no newline). Throws st::InputError for a station code that is
/// not 3 characters or a designation longer than 7.
[[nodiscard]] std::string mpc80Line(const AstrometricDetection& d, const SubmissionSettings& settings);
/// The whole 80-column message: the MPC1992 header lines COD (station), OBS (observers), MEA (measurer), TEL
/// (telescope), NET (astCat, when given), ACK, then one line per detection.
[[nodiscard]] SubmissionText formatMpc80(const std::vector<AstrometricDetection>& detections,
                                         const SubmissionSettings& settings);
/// The ADES PSV text: header blocks and the fields trkSub, mode, stn, obsTime, ra, dec, rmsRA, rmsDec,
/// astCat, mag, band, logSNR, remarks. Columns are padded to a common width (PSV allows blanks around
/// values).
[[nodiscard]] SubmissionText formatAdesPsv(const std::vector<AstrometricDetection>& detections,
                                           const SubmissionSettings& settings);

/// Calendar date of an MJD (UTC): year, month, day with fraction (proleptic Gregorian).
struct CalendarDate {
  int year = 0, month = 0;
  double day = 0.0;
};
[[nodiscard]] CalendarDate calendarFromMjd(double mjd) noexcept;
/// ISO 8601 "YYYY-MM-DDThh:mm:ss.sssZ" (milliseconds, rounded, carries handled).
[[nodiscard]] std::string isoUtcFromMjd(double mjd);
/// "HH MM SS.sss" and "sDD MM SS.ss" (sexagesimal, rounded with carries; RA wrapped to [0, 24h)).
[[nodiscard]] std::string sexagesimalRa(double raDeg);
[[nodiscard]] std::string sexagesimalDec(double decDeg);

}  // namespace st::report

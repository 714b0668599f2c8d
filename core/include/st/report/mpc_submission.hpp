#pragma once
// Astrometry for the Minor Planet Center: ADES (version 2022, PSV and XML; ades.hpp) and the MPC1992
// 80-column format, for detections a person labelled real (issue 8). Both are fixed by the MPC:
//   80-column: cols 1-5 number (blank), 6-12 provisional/temporary designation, 13 discovery asterisk,
//   14 note 1, 15 note 2 ('C' CCD, 'B' CMOS), 16-32 date "YYYY MM DD.dddddd" (UTC), 33-44 RA
//   "HH MM SS.sss", 45-56 Dec "sDD MM SS.ss", 57-65 blank, 66-70 magnitude ("22.9 "), 71 band,
//   72 astrometric catalogue code (star_catalogues.hpp), 73-77 blank, 78-80 observatory code.
//   ADES: obsContext observatory (mpcCode), submitter, observers, measurers, telescope (design, aperture,
//   detector), then one optical element per observation with trkSub, mode, stn, obsTime (ISO 8601 UTC with
//   'Z'), ra and dec (decimal degrees), rmsRA (RA cos Dec) and rmsDec (arcsec), astCat, mag and band,
//   logSNR = log10(SNR), remarks, in the order of submit.xsd's OpticalType.
// A file that would not validate is refused (st::InputError naming what is missing, submissionProblems())
// rather than written. Shift-and-stack users are asked by the MPC not to submit detections pulled out of
// noise: every line below `safeSnr` adds a warning (the CLI prints them on stderr, the GUI shows them).
#include <optional>
#include <string>
#include <vector>

#include "st/report/ades.hpp"
#include "st/report/submission_settings.hpp"

namespace st::report {

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
  int segment = 0;  ///< the fit segment this position is of (SegmentPosition::segment); 0: the whole fit
};

/// One warning per detection below `safeSnr` ("st00001 segment 2: SNR 6.10 is below the safe 7.0; ..."): the
/// MPC asks shift-and-stack users not to submit detections pulled out of the noise.
[[nodiscard]] std::vector<std::string> lowSnrWarnings(const std::vector<AstrometricDetection>& detections,
                                                      double safeSnr);

struct SubmissionText {
  std::string text;
  std::vector<std::string> warnings;  ///< low SNR, missing catalogue, truncated designation, ...
};

/// One 80-column line (exactly 80 characters, no newline; column 72, the catalogue code, blank as the MPC
/// wants it in submissions). Throws st::InputError for settings with submissionProblems(Mpc80) (station
/// code, catalogue) or a designation longer than 7.
[[nodiscard]] std::string mpc80Line(const AstrometricDetection& d, const SubmissionSettings& settings);
/// The whole 80-column message: the MPC1992 header lines COD (station), OBS (observers), MEA (measurer), TEL
/// (telescope), NET (the catalogue by the MPC's name: netCatalogueName()), ACK, AC2 (the contact e-mail, when
/// given; a warning when not), then one line per detection.
[[nodiscard]] SubmissionText formatMpc80(const std::vector<AstrometricDetection>& detections,
                                         const SubmissionSettings& settings);
/// The ADES document: obsContext from the settings, the fields trkSub, mode, stn, obsTime, ra, dec, rmsRA,
/// rmsDec, astCat, mag, band, logSNR, remarks (mag and band only where a magnitude is given, in -5..35;
/// rmsRA/rmsDec with 3 decimals, more for values below 0.0005", absent when they do not fit 7 characters).
/// Throws st::InputError listing submissionProblems(Ades) when there are any, and for a detection without a
/// valid position and epoch, a trkSub not 1-8 of [-A-Za-z0-9_], or a magnitude with a band that is not
/// 1-3 letters or digits. Warnings: no observer, a deprecated or unlisted astCat, low SNR, values left out.
[[nodiscard]] AdesDocument adesDocument(const std::vector<AstrometricDetection>& detections,
                                        const SubmissionSettings& settings,
                                        std::vector<std::string>& warnings);
/// adesDocument() as PSV (columns padded to a common width) and as XML.
[[nodiscard]] SubmissionText formatAdesPsv(const std::vector<AstrometricDetection>& detections,
                                           const SubmissionSettings& settings);
[[nodiscard]] SubmissionText formatAdesXml(const std::vector<AstrometricDetection>& detections,
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

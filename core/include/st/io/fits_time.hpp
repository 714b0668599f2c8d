#pragma once
// Frame times from FITS headers (ARCHITECTURE.md, "Time": exposure mid-time as MJD UTC plus exposure length).
#include <optional>
#include <string>
#include <string_view>

#include "st/common/fits_header.hpp"

namespace st::io {

/// MJD (UTC) of a civil date and time: Gregorian calendar, `seconds` since midnight.
double mjdFromCalendar(int year, int month, int day, double seconds);

/// Parses a FITS date: "YYYY-MM-DD", "YYYY-MM-DDThh:mm:ss[.s]" (also with a blank for 'T', or a trailing
/// 'Z'), or the old "DD/MM/YY" (YY < 100 means 19YY; 100..199 is read as 1900+YY, the year-2000 bug of some
/// writers). Returns the MJD of the date (plus the time when present) and whether a time was present.
/// Returns nullopt when the text is not a date.
struct ParsedDate {
  double mjd = 0.0;
  bool hasTime = false;
};
std::optional<ParsedDate> parseFitsDate(std::string_view text);

/// Parses a time of day "hh:mm:ss[.s]" (or "hh mm ss") into seconds since midnight; nullopt if malformed.
std::optional<double> parseTimeOfDay(std::string_view text);

/// A value from an MJD keyword: values > 2400000 are Julian Dates and converted (JD - 2400000.5).
double mjdFromMjdOrJd(double value);

/// What a header says about a frame's time.
struct FrameTime {
  std::optional<double> mjdMid;     ///< exposure mid-time, MJD UTC; empty when the header has no time
  std::optional<double> exposureS;  ///< EXPTIME or EXPOSURE (s); empty when absent
  std::string source;               ///< the keywords used, e.g. "DATE-OBS+UTCSTART (start) + EXPTIME/2"
};

/// Reads the frame time of one header. Order: DATE-AVG, MJD-AVG / MJD-MID (mid-times); DATE-OBS with a time;
/// DATE-OBS date only plus TIME-OBS / UTCSTART / UTC-OBS / UT / UTSTART / TIME-BEG; MJD-OBS; JD-OBS. Start
/// times become mid-times by adding half the exposure, unless the keyword's comment says it is a mid-time.
/// `where` (e.g. "a.fits HDU 1") prefixes error messages. Throws st::InputError naming the keyword and its
/// value when a time keyword is present but malformed.
FrameTime frameTimeFromHeader(const FitsHeader& header, const std::string& where);

}  // namespace st::io

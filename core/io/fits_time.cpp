#include "st/io/fits_time.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>

#include "st/common/error.hpp"
#include "st/common/units.hpp"

namespace st::io {
namespace {

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

std::string_view trimView(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t'))
    s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == 'Z'))
    s.remove_suffix(1);
  return s;
}

bool readInt(std::string_view s, int& out) {
  if (s.empty()) return false;
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
  return ec == std::errc() && ptr == s.data() + s.size();
}

// A keyword's comment says the value is a mid-exposure time ("mid", "middle", "center") and not a start.
bool commentSaysMid(const FitsCard& card) {
  const std::string c = lower(card.comment);
  if (c.find("start") != std::string::npos || c.find("begin") != std::string::npos) return false;
  return c.find("mid") != std::string::npos || c.find("center") != std::string::npos ||
         c.find("centre") != std::string::npos;
}

[[noreturn]] void badValue(const std::string& where, std::string_view key, const std::string& value,
                           const std::string& expected) {
  throw InputError(where + ": header keyword " + std::string(key) + " = '" + value + "' is not " + expected);
}

double numberOrThrow(const FitsHeader& h, std::string_view key, const std::string& where) {
  try {
    return h.getDouble(key).value();
  } catch (const InputError&) {
    badValue(where, key, h.getString(key).value_or(""), "a number");
  }
}

bool validCalendar(int y, int m, int d) {
  return y >= 1 && y <= 9999 && m >= 1 && m <= 12 && d >= 1 && d <= 31;
}

}  // namespace

double mjdFromCalendar(int year, int month, int day, double seconds) {
  // Fliegel & Van Flandern (1968) Julian Day Number for the Gregorian calendar.
  const long a = (14 - month) / 12;
  const long y = year + 4800 - a;
  const long m = month + 12 * a - 3;
  const long jdn = day + (153 * m + 2) / 5 + 365 * y + y / 4 - y / 100 + y / 400 - 32045;
  return static_cast<double>(jdn - 2400001) + seconds / kSecondsPerDay;
}

std::optional<double> parseTimeOfDay(std::string_view text) {
  text = trimView(text);
  const char sep = text.find(':') != std::string_view::npos ? ':' : ' ';
  const auto p1 = text.find(sep);
  if (p1 == std::string_view::npos) return std::nullopt;
  const auto p2 = text.find(sep, p1 + 1);
  if (p2 == std::string_view::npos) return std::nullopt;
  int hh = 0;
  int mm = 0;
  if (!readInt(text.substr(0, p1), hh) || !readInt(text.substr(p1 + 1, p2 - p1 - 1), mm)) return std::nullopt;
  double ss = 0.0;
  const auto sec = text.substr(p2 + 1);
  const auto [ptr, ec] = std::from_chars(sec.data(), sec.data() + sec.size(), ss);
  if (sec.empty() || ec != std::errc() || ptr != sec.data() + sec.size()) return std::nullopt;
  if (hh < 0 || hh > 24 || mm < 0 || mm > 59 || !(ss >= 0.0 && ss < 61.0)) return std::nullopt;
  return hh * 3600.0 + mm * 60.0 + ss;
}

std::optional<ParsedDate> parseFitsDate(std::string_view text) {
  text = trimView(text);
  int y = 0;
  int m = 0;
  int d = 0;
  if (text.size() >= 8 && text[2] == '/' && text[5] == '/') {  // old DD/MM/YY
    if (!readInt(text.substr(0, 2), d) || !readInt(text.substr(3, 2), m) || !readInt(text.substr(6), y)) {
      return std::nullopt;
    }
    if (y < 0 || y >= 200) return std::nullopt;
    y += 1900;
    if (!validCalendar(y, m, d)) return std::nullopt;
    return ParsedDate{mjdFromCalendar(y, m, d, 0.0), false};
  }
  if (text.size() < 10 || text[4] != '-' || text[7] != '-') return std::nullopt;
  if (!readInt(text.substr(0, 4), y) || !readInt(text.substr(5, 2), m) || !readInt(text.substr(8, 2), d)) {
    return std::nullopt;
  }
  if (!validCalendar(y, m, d)) return std::nullopt;
  if (text.size() == 10) return ParsedDate{mjdFromCalendar(y, m, d, 0.0), false};
  if (text[10] != 'T' && text[10] != ' ') return std::nullopt;
  const auto seconds = parseTimeOfDay(text.substr(11));
  if (!seconds) return std::nullopt;
  return ParsedDate{mjdFromCalendar(y, m, d, *seconds), true};
}

double mjdFromMjdOrJd(double value) {
  return value > 2400000.0 ? value - 2400000.5 : value;
}

FrameTime frameTimeFromHeader(const FitsHeader& h, const std::string& where) {
  FrameTime t;
  std::string expKey;
  for (const char* key : {"EXPTIME", "EXPOSURE", "EXP_TIME", "ITIME"}) {
    if (!h.has(key) || h.getString(key)->empty()) continue;
    const double e = numberOrThrow(h, key, where);
    if (!(e >= 0.0) || !std::isfinite(e))
      badValue(where, key, h.getString(key).value_or(""), "an exposure >= 0 s");
    t.exposureS = e;
    expKey = key;
    break;
  }
  const double half = t.exposureS.value_or(0.0) / 2.0 / kSecondsPerDay;
  auto finish = [&](double mjd, bool isMid, const std::string& src) {
    if (!std::isfinite(mjd) || mjd < -100000.0 || mjd > 1000000.0) {
      throw InputError(where + ": time from " + src + " is out of range (MJD " + std::to_string(mjd) + ")");
    }
    t.mjdMid = isMid ? mjd : mjd + half;
    t.source =
        src + (isMid ? " (mid)"
                     : " (start)" + (expKey.empty() ? std::string(", no exposure") : " + " + expKey + "/2"));
    return t;
  };
  if (const FitsCard* c = h.find("DATE-AVG"); c != nullptr && !c->value.empty()) {
    const auto d = parseFitsDate(c->value);
    if (!d || !d->hasTime) badValue(where, "DATE-AVG", c->value, "a date and time YYYY-MM-DDThh:mm:ss");
    return finish(d->mjd, true, "DATE-AVG");
  }
  for (const char* key : {"MJD-AVG", "MJD-MID", "MJD_MID"}) {
    if (h.has(key) && !h.getString(key)->empty())
      return finish(mjdFromMjdOrJd(numberOrThrow(h, key, where)), true, key);
  }
  const FitsCard* dateObs = h.find("DATE-OBS");
  if (dateObs != nullptr && !dateObs->value.empty()) {
    const auto d = parseFitsDate(dateObs->value);
    if (!d) badValue(where, "DATE-OBS", dateObs->value, "a date (YYYY-MM-DD[Thh:mm:ss] or DD/MM/YY)");
    if (d->hasTime) return finish(d->mjd, commentSaysMid(*dateObs), "DATE-OBS");
    for (const char* key : {"TIME-OBS", "UTCSTART", "UTC-OBS", "UT", "UTSTART", "TIME-BEG", "UTC"}) {
      const FitsCard* c = h.find(key);
      if (c == nullptr || c->value.empty()) continue;
      if (const auto full = parseFitsDate(c->value); full && full->hasTime) {
        return finish(full->mjd, commentSaysMid(*c), key);
      }
      const auto s = parseTimeOfDay(c->value);
      if (!s) badValue(where, key, c->value, "a time of day hh:mm:ss");
      return finish(d->mjd + *s / kSecondsPerDay, commentSaysMid(*c), "DATE-OBS+" + std::string(key));
    }
  }
  for (const char* key : {"MJD-OBS", "MJD_OBS", "JD-OBS", "JD_OBS"}) {
    const FitsCard* c = h.find(key);
    if (c == nullptr || c->value.empty()) continue;
    return finish(mjdFromMjdOrJd(numberOrThrow(h, key, where)), commentSaysMid(*c), key);
  }
  return t;
}

}  // namespace st::io

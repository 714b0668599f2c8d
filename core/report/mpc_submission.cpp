#include "st/report/mpc_submission.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "st/common/error.hpp"

namespace st::report {
namespace {

std::string fmt(const char* f, auto... args) {
  char buf[256];
  std::snprintf(buf, sizeof buf, f, args...);
  return buf;
}

/// Civil date of an integer MJD (Fliegel & Van Flandern 1968 on the Julian day number).
void civilFromMjdDay(long long mjdDay, int& year, int& month, int& day) {
  long long l = mjdDay + 2400001 + 68569;
  const long long n = 4 * l / 146097;
  l -= (146097 * n + 3) / 4;
  const long long i = 4000 * (l + 1) / 1461001;
  l = l - 1461 * i / 4 + 31;
  const long long j = 80 * l / 2447;
  day = static_cast<int>(l - 2447 * j / 80);
  l = j / 11;
  month = static_cast<int>(j + 2 - 12 * l);
  year = static_cast<int>(100 * (n - 49) + i + l);
}

long long floorDiv(long long a, long long b) {
  return a / b - ((a % b != 0) && ((a < 0) != (b < 0)));
}

// ADES ra: decimal degrees in [0, 360), 7 decimals; a value that rounds up to 360 is written as 0.
std::string adesRa(double raDeg) {
  const std::string text = fmt("%.7f", std::fmod(std::fmod(raDeg, 360.0) + 360.0, 360.0));
  return text == "360.0000000" ? "0.0000000" : text;
}

void checkSettings(const SubmissionSettings& s) {
  if (s.stationCode.size() != 3) {
    throw InputError("MPC station code must be 3 characters, got '" + s.stationCode + "' (set --station)");
  }
}

void checkDetection(const AstrometricDetection& d) {
  if (!std::isfinite(d.raDeg) || !std::isfinite(d.decDeg) || std::abs(d.decDeg) > 90.0 ||
      !std::isfinite(d.mjdUtc) || d.mjdUtc <= 0.0) {
    throw InputError("detection '" + d.trkSub + "' has no valid position or epoch (RA " +
                     std::to_string(d.raDeg) + ", Dec " + std::to_string(d.decDeg) + ", MJD " +
                     std::to_string(d.mjdUtc) + ")");
  }
}

void lowSnrWarnings(const std::vector<AstrometricDetection>& ds, const SubmissionSettings& s,
                    std::vector<std::string>& warnings) {
  for (const auto& d : ds) {
    if (d.snr < s.safeSnr) {
      warnings.push_back(
          fmt("%s: SNR %.2f is below the safe %.1f; the MPC rejects shift-and-stack detections "
              "pulled out of the noise: confirm it before submitting",
              d.trkSub.c_str(), d.snr, s.safeSnr));
    }
  }
}

}  // namespace

CalendarDate calendarFromMjd(double mjd) noexcept {
  const double dayFloor = std::floor(mjd);
  CalendarDate c;
  int d = 0;
  civilFromMjdDay(static_cast<long long>(dayFloor), c.year, c.month, d);
  c.day = d + (mjd - dayFloor);
  return c;
}

std::string isoUtcFromMjd(double mjd) {
  const long long ms = std::llround(mjd * 86400000.0);
  const long long day = floorDiv(ms, 86400000LL);
  long long rem = ms - day * 86400000LL;
  int y = 0, mo = 0, d = 0;
  civilFromMjdDay(day, y, mo, d);
  const int h = static_cast<int>(rem / 3600000);
  rem %= 3600000;
  const int mi = static_cast<int>(rem / 60000);
  rem %= 60000;
  return fmt("%04d-%02d-%02dT%02d:%02d:%02d.%03dZ", y, mo, d, h, mi, static_cast<int>(rem / 1000),
             static_cast<int>(rem % 1000));
}

std::string sexagesimalRa(double raDeg) {
  const long long total = 24LL * 3600 * 1000;
  long long ms = std::llround(raDeg / 15.0 * 3600.0 * 1000.0) % total;
  if (ms < 0) ms += total;
  const int h = static_cast<int>(ms / 3600000);
  const int m = static_cast<int>(ms / 60000 % 60);
  const long long s = ms % 60000;
  return fmt("%02d %02d %02lld.%03lld", h, m, s / 1000, s % 1000);
}

std::string sexagesimalDec(double decDeg) {
  const long long cas = std::llround(std::abs(decDeg) * 3600.0 * 100.0);  // centi-arcsec
  const int d = static_cast<int>(cas / 360000);
  const int m = static_cast<int>(cas / 6000 % 60);
  const long long s = cas % 6000;
  return fmt("%c%02d %02d %02lld.%02lld", decDeg < 0.0 && cas > 0 ? '-' : '+', d, m, s / 100, s % 100);
}

std::string mpc80Line(const AstrometricDetection& det, const SubmissionSettings& s) {
  checkSettings(s);
  if (det.trkSub.empty() || det.trkSub.size() > 7) {
    throw InputError("80-column designation must be 1 to 7 characters, got '" + det.trkSub + "'");
  }
  checkDetection(det);
  std::string line(80, ' ');
  auto put = [&](int col1, const std::string& text) { line.replace(col1 - 1, text.size(), text); };
  put(6, det.trkSub);
  line[14] = s.detector == "CMO" ? 'B' : 'C';  // column 15, note 2
  const long long micro = std::llround(det.mjdUtc * 1e6);
  const long long day = floorDiv(micro, 1000000LL);
  int y = 0, mo = 0, d = 0;
  civilFromMjdDay(day, y, mo, d);
  put(16, fmt("%04d %02d %02d.%06lld", y, mo, d, micro - day * 1000000LL));
  put(33, sexagesimalRa(det.raDeg));
  put(45, sexagesimalDec(det.decDeg));
  if (det.mag && std::isfinite(*det.mag)) {
    put(66, fmt("%4.1f", *det.mag));
    if (!det.band.empty()) line[70] = det.band[0];
  }
  line[71] = s.mpcCatalogCode;
  put(78, s.stationCode);
  return line;
}

SubmissionText formatMpc80(const std::vector<AstrometricDetection>& ds, const SubmissionSettings& s) {
  checkSettings(s);
  SubmissionText out;
  // MPC1992 header lines (3-letter code, a blank, text; at most 80 characters each).
  auto header = [&](const char* code, const std::string& text) {
    if (!text.empty()) out.text += (std::string(code) + " " + text).substr(0, 80) + "\n";
  };
  const std::string measurer =
      !s.measurer.empty() ? s.measurer : s.observers.substr(0, s.observers.find(','));
  header("COD", s.stationCode);
  header("OBS", s.observers);
  header("MEA", measurer);
  header("TEL", s.apertureM > 0.0
                    ? fmt("%.2f-m %s + %s", s.apertureM, s.telescopeDesign.c_str(), s.detector.c_str())
                    : s.telescopeDesign + " + " + s.detector);
  header("NET", s.astCat);
  header("ACK", "synthtrack astrometry, " + std::to_string(ds.size()) + " observation(s)");
  if (s.observers.empty())
    out.warnings.push_back("80-column: no observer name for the OBS line (set --observer)");
  for (const auto& d : ds)
    out.text += mpc80Line(d, s) + "\n";
  if (s.mpcCatalogCode == ' ') {
    out.warnings.push_back(
        "80-column: column 72 (astrometric catalogue code) is blank; set the catalogue of "
        "the WCS solution");
  }
  lowSnrWarnings(ds, s, out.warnings);
  return out;
}

SubmissionText formatAdesPsv(const std::vector<AstrometricDetection>& ds, const SubmissionSettings& s) {
  checkSettings(s);
  SubmissionText out;
  std::string& t = out.text;
  t += "# version=2017\n# observatory\n! mpcCode " + s.stationCode + "\n";
  const std::string measurer =
      !s.measurer.empty() ? s.measurer : s.observers.substr(0, s.observers.find(','));
  const std::string submitter = !s.submitter.empty() ? s.submitter : measurer;
  if (!submitter.empty()) t += "# submitter\n! name " + submitter + "\n";
  if (!s.observers.empty()) {
    t += "# observers\n";
    std::size_t start = 0;
    while (start <= s.observers.size()) {
      const std::size_t comma = std::min(s.observers.find(',', start), s.observers.size());
      std::string name = s.observers.substr(start, comma - start);
      name.erase(0, name.find_first_not_of(' '));
      if (!name.empty()) t += "! name " + name + "\n";
      start = comma + 1;
    }
  } else {
    out.warnings.push_back("ADES: no observer name (set --observer)");
  }
  if (!measurer.empty()) t += "# measurers\n! name " + measurer + "\n";
  t += "# telescope\n! design " + s.telescopeDesign + "\n";
  if (s.apertureM > 0.0) t += fmt("! aperture %.2f\n", s.apertureM);
  t += "! detector " + s.detector + "\n";
  if (s.astCat.empty())
    out.warnings.push_back("ADES: astCat (catalogue of the WCS solution) is empty; ADES requires it");

  const std::vector<std::string> names = {"trkSub", "mode",   "stn", "obsTime", "ra",     "dec",    "rmsRA",
                                          "rmsDec", "astCat", "mag", "band",    "logSNR", "remarks"};
  std::vector<std::vector<std::string>> rows;
  for (const auto& d : ds) {
    checkDetection(d);
    if (d.trkSub.empty() || d.trkSub.size() > 8)
      throw InputError("ADES trkSub must be 1 to 8 characters, got '" + d.trkSub + "'");
    const bool hasMag = d.mag && std::isfinite(*d.mag);
    rows.push_back({d.trkSub, s.detector, s.stationCode, isoUtcFromMjd(d.mjdUtc), adesRa(d.raDeg),
                    fmt("%+.7f", d.decDeg), d.sigmaRaArcsec ? fmt("%.3f", *d.sigmaRaArcsec) : "",
                    d.sigmaDecArcsec ? fmt("%.3f", *d.sigmaDecArcsec) : "", s.astCat,
                    hasMag ? fmt("%.2f", *d.mag) : "", hasMag ? d.band : "",
                    d.snr > 0.0 ? fmt("%.2f", std::log10(d.snr)) : "",
                    "synthetic tracking (shift-and-stack)"});
  }
  std::vector<std::size_t> width(names.size());
  for (std::size_t i = 0; i < names.size(); ++i) {
    width[i] = names[i].size();
    for (const auto& r : rows)
      width[i] = std::max(width[i], r[i].size());
  }
  auto emit = [&](const std::vector<std::string>& fields) {
    for (std::size_t i = 0; i < fields.size(); ++i) {
      std::string f = fields[i];
      if (i + 1 < fields.size()) f.resize(width[i], ' ');
      t += f + (i + 1 < fields.size() ? "|" : "\n");
    }
  };
  emit(names);
  for (const auto& r : rows)
    emit(r);
  lowSnrWarnings(ds, s, out.warnings);
  return out;
}

}  // namespace st::report

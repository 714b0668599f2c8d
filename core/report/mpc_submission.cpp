#include "st/report/mpc_submission.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <regex>

#include "st/common/error.hpp"
#include "st/report/star_catalogues.hpp"

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

void checkSettings(const SubmissionSettings& s, SubmissionFormat format) {
  if (const auto problems = submissionProblems(s, format); !problems.empty())
    throw InputError(problemsText(problems, format));
}

// A positive decimal of at most `maxChars` characters (ADES PosDecimalTypeW*): 3 decimals, more for a value
// that would round to zero, fewer for a large one; empty when none fits.
std::string positiveDecimal(double v, std::size_t maxChars) {
  if (!(v > 0.0) || !std::isfinite(v)) return {};
  for (int decimals = 3; decimals >= 0; --decimals) {
    const std::string s = fmt("%.*f", decimals, v);
    if (s.size() <= maxChars && std::stod(s) > 0.0) return s;
  }
  for (int decimals = 4; decimals + 2 <= static_cast<int>(maxChars); ++decimals) {
    const std::string s = fmt("%.*f", decimals, v);
    if (std::stod(s) > 0.0) return s;
  }
  return {};
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
  for (auto& w : lowSnrWarnings(ds, s.safeSnr))
    warnings.push_back(std::move(w));
}

}  // namespace

std::vector<std::string> lowSnrWarnings(const std::vector<AstrometricDetection>& ds, double safeSnr) {
  std::vector<std::string> out;
  for (const auto& d : ds) {
    if (!(d.snr < safeSnr)) continue;
    const std::string which = d.segment > 0 ? d.trkSub + " segment " + std::to_string(d.segment) : d.trkSub;
    out.push_back(
        fmt("%s: SNR %.2f is below the safe %.1f; the MPC rejects shift-and-stack detections "
            "pulled out of the noise: confirm it before submitting",
            which.c_str(), d.snr, safeSnr));
  }
  return out;
}

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
  checkSettings(s, SubmissionFormat::Mpc80);
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
  // Column 72 stays blank: the MPC fills it from the NET line ("Catalogue Codes": "On new submissions,
  // column 72 must be blank").
  put(78, s.stationCode);
  return line;
}

namespace {

// Observers are separated by commas: "Doe, J." becomes two of them, "Doe" and "J.". A name of initials alone
// is said (not refused: it may be meant).
void initialsWarnings(const SubmissionSettings& s, std::vector<std::string>& warnings) {
  static const std::regex kInitials(R"(([A-Z]\.\s*)+)");
  for (const auto& name : observerNames(s))
    if (std::regex_match(name, kInitials)) {
      const std::string w = "observer '" + name +
                            "' is initials alone: observers are separated by commas (write 'J. Doe', not "
                            "'Doe, J.')";
      if (std::find(warnings.begin(), warnings.end(), w) == warnings.end()) warnings.push_back(w);
    }
}

}  // namespace

SubmissionText formatMpc80(const std::vector<AstrometricDetection>& ds, const SubmissionSettings& s) {
  checkSettings(s, SubmissionFormat::Mpc80);
  SubmissionText out;
  // MPC1992 header lines (3-letter code, a blank, text; at most 80 characters each).
  auto header = [&](const char* code, const std::string& text) {
    if (!text.empty()) out.text += (std::string(code) + " " + text).substr(0, 80) + "\n";
  };
  const std::string measurer = measurerOf(s);
  header("COD", s.stationCode);
  header("OBS", s.observers);
  header("MEA", measurer);
  header("TEL", s.apertureM > 0.0
                    ? fmt("%.2f-m %s + %s", s.apertureM, s.telescopeDesign.c_str(), s.detector.c_str())
                    : s.telescopeDesign + " + " + s.detector);
  header("NET", netCatalogueName(s));
  if (const char code = resolvedCatalogueCode(s); code == ' ')
    out.warnings.push_back("80-column: astCat '" + s.astCat +
                           "' is not in the MPC's list of catalogue codes: the NET line names it as given");
  header("ACK", "synthtrack astrometry, " + std::to_string(ds.size()) + " observation(s)");
  header("AC2", s.contactEmail);
  if (s.contactEmail.empty())
    out.warnings.push_back(
        "80-column: no contact e-mail for the AC2 line, where the MPC sends its acknowledgment (set "
        "--contact-email)");
  if (s.observers.empty())
    out.warnings.push_back("80-column: no observer name for the OBS line (set --observer)");
  initialsWarnings(s, out.warnings);
  for (const auto& d : ds)
    out.text += mpc80Line(d, s) + "\n";
  lowSnrWarnings(ds, s, out.warnings);
  return out;
}

namespace {

AdesContextBlock names(const char* block, const std::vector<std::string>& people) {
  AdesContextBlock b{block, {}, {}};
  for (const auto& n : people)
    b.items.emplace_back("name", n);
  return b;
}

std::vector<AdesContextBlock> adesContext(const SubmissionSettings& s) {
  const std::string measurer = measurerOf(s);
  const auto observers = observerNames(s);
  std::vector<AdesContextBlock> c;
  c.push_back({"observatory", {}, {{"mpcCode", s.stationCode}}});
  c.push_back({"submitter", {}, {{"name", s.submitter.empty() ? measurer : s.submitter}}});
  if (!observers.empty()) c.push_back(names("observers", observers));
  c.push_back(names("measurers", {measurer}));
  c.push_back({"telescope",
               {},
               {{"design", s.telescopeDesign},
                {"aperture", positiveDecimal(s.apertureM, 6)},
                {"detector", s.detector}}});
  return c;
}

void checkAdesDetection(const AstrometricDetection& d) {
  static const std::regex kTrkSub("[-A-Za-z0-9_]{1,8}");
  static const std::regex kBand("[A-Za-z0-9_]{1,3}");
  checkDetection(d);
  if (!std::regex_match(d.trkSub, kTrkSub))
    throw InputError("ADES trkSub must be 1 to 8 of letters, digits, '-', '_', got '" + d.trkSub + "'");
  if (d.mag && std::isfinite(*d.mag) && !std::regex_match(d.band, kBand))
    throw InputError("detection '" + d.trkSub +
                     "': the magnitude's band must be 1-3 letters or digits, got '" + d.band + "'");
}

std::vector<std::string> adesRow(const AstrometricDetection& d, const SubmissionSettings& s,
                                 std::vector<std::string>& warnings) {
  const bool hasMag = d.mag && std::isfinite(*d.mag) && *d.mag >= -5.0 && *d.mag <= 35.0;
  if (d.mag && !hasMag)
    warnings.push_back(d.trkSub + ": magnitude " + fmt("%g", *d.mag) + " outside ADES's -5..35, left out");
  const auto rms = [&](const std::optional<double>& v, const char* name) {
    if (!v) return std::string();
    std::string text = positiveDecimal(*v, 7);
    if (text.empty())
      warnings.push_back(d.trkSub + ": " + name + " " + fmt("%g", *v) +
                         "\" not positive "
                         "or too large for ADES, left out");
    return text;
  };
  std::string logSnr;
  if (d.snr > 0.0 && std::isfinite(d.snr)) {
    logSnr = fmt("%.2f", std::log10(d.snr));
    if (logSnr.size() - (logSnr[0] == '-') > 5) logSnr.clear();  // DecimalTypeW6
  }
  return {d.trkSub,
          s.detector,
          s.stationCode,
          isoUtcFromMjd(d.mjdUtc),
          adesRa(d.raDeg),
          fmt("%+.7f", d.decDeg),
          rms(d.sigmaRaArcsec, "rmsRA"),
          rms(d.sigmaDecArcsec, "rmsDec"),
          s.astCat,
          hasMag ? fmt("%.2f", *d.mag) : "",
          hasMag ? d.band : "",
          logSnr,
          "synthetic tracking (shift-and-stack)"};
}

}  // namespace

AdesDocument adesDocument(const std::vector<AstrometricDetection>& ds, const SubmissionSettings& s,
                          std::vector<std::string>& warnings) {
  checkSettings(s, SubmissionFormat::Ades);
  if (observerNames(s).empty()) warnings.push_back("ADES: no observer name (set --observer)");
  initialsWarnings(s, warnings);
  if (const StarCatalogue* c = findStarCatalogue(s.astCat); !c) {
    warnings.push_back(
        "ADES: astCat '" + s.astCat +
        "' is not in the MPC's list of catalogues (a batch naming an unlisted one is rejected)");
  } else if (c->deprecated) {
    warnings.push_back("ADES: astCat '" + s.astCat + "' is deprecated by the MPC; prefer Gaia3 or Gaia2");
  }
  AdesDocument doc;
  doc.context = adesContext(s);
  doc.fields = {"trkSub", "mode",   "stn", "obsTime", "ra",     "dec",    "rmsRA",
                "rmsDec", "astCat", "mag", "band",    "logSNR", "remarks"};
  for (const auto& d : ds) {
    checkAdesDetection(d);
    doc.rows.push_back(adesRow(d, s, warnings));
  }
  lowSnrWarnings(ds, s, warnings);
  return doc;
}

SubmissionText formatAdesPsv(const std::vector<AstrometricDetection>& ds, const SubmissionSettings& s) {
  SubmissionText out;
  out.text = adesPsvText(adesDocument(ds, s, out.warnings));
  return out;
}

SubmissionText formatAdesXml(const std::vector<AstrometricDetection>& ds, const SubmissionSettings& s) {
  SubmissionText out;
  out.text = adesXmlText(adesDocument(ds, s, out.warnings));
  return out;
}

}  // namespace st::report

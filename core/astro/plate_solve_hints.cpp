// Plate solving: the header's hints and the index files (astro/plate_solve.hpp).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>

#include "st/astro/plate_solve.hpp"
#include "st/common/error.hpp"

namespace st::astro {
namespace {

/// Smallest quad size of astrometry.net index scale N, arcmin (its documentation; N = 0..19); N + 1's
/// entry is the largest. Debian's tycho2 packages name the same ranges (07: 22'-30', 08: 30'-44', ...).
constexpr double kQuadArcmin[] = {2.0,  2.8,  4.0,   5.6,   8.0,   11.0,  16.0,  22.0,  30.0,   44.0,  60.0,
                                  85.0, 120., 170.0, 240.0, 340.0, 480.0, 680.0, 1000., 1400.0, 2000.0};

std::optional<double> number(const FitsHeader& h, const char* key) {
  try {
    const auto v = h.getDouble(key);
    if (v && std::isfinite(*v) && *v > 0.0) return v;
  } catch (const std::exception&) {
  }
  return std::nullopt;
}

/// "08:18:29.9", "08 18 29.9" or "124.62"; `hours` scales a sexagesimal value by 15 (RA).
std::optional<double> angle(const FitsHeader& h, const char* key, bool hours) {
  const auto s = h.getString(key);
  if (!s || s->empty()) return std::nullopt;
  std::string t = *s;
  std::replace(t.begin(), t.end(), ':', ' ');
  std::istringstream in(t);
  std::vector<std::string> parts;
  for (std::string p; in >> p;)
    parts.push_back(p);
  try {
    if (parts.size() == 1) return std::stod(parts[0]);
    if (parts.size() != 3) return std::nullopt;
    const bool negative = parts[0].find('-') != std::string::npos;
    const double v =
        std::abs(std::stod(parts[0])) + std::stod(parts[1]) / 60.0 + std::stod(parts[2]) / 3600.0;
    return (negative ? -v : v) * (hours ? 15.0 : 1.0);
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

/// The binning of an unbinned pixel scale: CCDSUM "3 3", else XBINNING, else 1.
double binning(const FitsHeader& h) {
  if (const auto s = h.getString("CCDSUM")) {
    std::istringstream in(*s);
    double b = 0.0;
    if (in >> b && b >= 1.0) return b;
  }
  if (const auto b = number(h, "XBINNING")) return *b;
  return 1.0;
}

}  // namespace

PlateSolveHints plateSolveHints(const FitsHeader& header) {
  PlateSolveHints out;
  for (const char* key : {"SECPIX", "SECPIXX", "PIXSCALE", "PIXSCAL1", "SCALE"}) {
    if (const auto v = number(header, key)) {
      out.scaleArcsecPerPx = *v;
      out.scaleSource = key;
      break;
    }
  }
  if (!out.scaleArcsecPerPx) {
    if (const auto v = number(header, "PIXSCAL")) {
      out.scaleArcsecPerPx = *v * binning(header);
      out.scaleSource = "PIXSCAL x binning";
    }
  }
  const char* pairs[][2] = {{"RA", "DEC"}, {"OBJCTRA", "OBJCTDEC"}, {"TELRA", "TELDEC"}};
  for (const auto& p : pairs) {
    const auto raText = header.getString(p[0]);
    const bool sexagesimal =
        raText && (raText->find(':') != std::string::npos || raText->find(' ') != std::string::npos);
    const auto ra = angle(header, p[0], sexagesimal);
    const auto dec = angle(header, p[1], false);
    if (ra && dec && *ra >= 0.0 && *ra < 360.0 && std::abs(*dec) <= 90.0) {
      out.raDeg = ra;
      out.decDeg = dec;
      out.pointingSource = std::string(p[0]) + "/" + p[1];
      break;
    }
  }
  return out;
}

void applyHints(PlateSolveParams& params, const PlateSolveHints& hints) {
  if (!params.scaleArcsecPerPx) params.scaleArcsecPerPx = hints.scaleArcsecPerPx;
  if (!params.raDeg || !params.decDeg) {
    params.raDeg = hints.raDeg;
    params.decDeg = hints.decDeg;
  }
}

std::pair<double, double> quadSizeArcmin(int scale) {
  if (scale < 0 || scale > 19) throw InputError("index scale must be 0..19, got " + std::to_string(scale));
  return {kQuadArcmin[scale], kQuadArcmin[scale + 1]};
}

std::vector<IndexFile> findIndexFiles(const std::vector<std::string>& dirs) {
  static const std::regex name(R"(^index-(?:tycho2-(\d\d)|\d\d(\d\d))(?:[-.].*)?\.fits$)");
  std::vector<IndexFile> out;
  for (const auto& dir : dirs) {
    std::error_code ec;
    for (const auto& entry : std::filesystem::directory_iterator(dir, ec)) {
      const std::string file = entry.path().filename().string();
      std::smatch m;
      if (!std::regex_match(file, m, name)) continue;
      const int scale = std::stoi(m[1].matched ? m[1].str() : m[2].str());
      if (scale < 0 || scale > 19) continue;
      out.push_back(IndexFile{entry.path().string(), scale, kQuadArcmin[scale], kQuadArcmin[scale + 1]});
    }
  }
  std::sort(out.begin(), out.end(), [](const IndexFile& a, const IndexFile& b) { return a.path < b.path; });
  return out;
}

std::vector<std::string> configIndexDirs(const std::string& configPath) {
  std::ifstream in(configPath);
  std::vector<std::string> dirs;
  for (std::string line; std::getline(in, line);) {
    std::istringstream words(line);
    std::string key, value;
    if (!(words >> key >> value) || key.front() == '#') continue;
    if (key == "add_path") {
      dirs.push_back(value);
    } else if (key == "index" && value.find('/') != std::string::npos) {
      dirs.push_back(std::filesystem::path(value).parent_path().string());
    }
  }
  return dirs;
}

bool indexSuitsField(const IndexFile& index, double fieldSideArcmin, double fieldDiagonalArcmin) {
  return index.quadMaxArcmin >= 0.1 * fieldSideArcmin && index.quadMinArcmin <= fieldDiagonalArcmin;
}

std::vector<std::string> indexPackagesFor(double fieldArcmin) {
  const double lo = 0.1 * fieldArcmin, hi = fieldArcmin * std::sqrt(2.0);
  std::vector<std::string> out;
  for (int scale = 7; scale <= 9; ++scale) {
    if (kQuadArcmin[scale + 1] >= lo && kQuadArcmin[scale] <= hi) {
      char name[64];
      std::snprintf(name, sizeof name, "astrometry-data-tycho2-%02d-littleendian", scale);
      out.emplace_back(name);
    }
  }
  if (kQuadArcmin[20] >= lo && kQuadArcmin[10] <= hi)
    out.emplace_back("astrometry-data-tycho2-10-19-littleendian");
  return out;
}

}  // namespace st::astro

#include "st/vet/known_objects.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <numbers>

#include "st/common/error.hpp"

namespace st::vet {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

std::string trim(std::string s) {
  const auto b = s.find_first_not_of(" \t\r\n");
  if (b == std::string::npos) return {};
  const auto e = s.find_last_not_of(" \t\r\n");
  s = s.substr(b, e - b + 1);
  if (s.size() >= 2 && s.front() == '"' && s.back() == '"') s = s.substr(1, s.size() - 2);
  return s;
}

std::string lower(std::string s) {
  for (auto& c : s)
    c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

/// Splits on commas outside double quotes.
std::vector<std::string> splitCsv(const std::string& line) {
  std::vector<std::string> out(1);
  bool quoted = false;
  for (char c : line) {
    if (c == '"') quoted = !quoted;
    if (c == ',' && !quoted) {
      out.emplace_back();
    } else {
      out.back() += c;
    }
  }
  for (auto& f : out)
    f = trim(f);
  return out;
}

double parseNumber(const std::string& text, const std::string& where) {
  double v = 0.0;
  const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || ptr != text.data() + text.size() || !std::isfinite(v)) {
    throw InputError(where + ": '" + text + "' is not a number");
  }
  return v;
}

}  // namespace

std::vector<KnownObject> readKnownObjects(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError("cannot read known-object list '" + path + "'");
  std::string line;
  int lineNo = 0;
  std::map<std::string, std::size_t> col;
  while (std::getline(in, line)) {
    ++lineNo;
    if (trim(line).empty() || trim(line)[0] == '#') continue;
    const auto names = splitCsv(line);
    for (std::size_t i = 0; i < names.size(); ++i)
      col[lower(names[i])] = i;
    break;
  }
  const bool arcsec = col.count("ra_rate_arcsec_min") && col.count("dec_rate_arcsec_min");
  const bool degDay = col.count("ra_rate_deg_day") && col.count("dec_rate_deg_day");
  for (const char* need : {"name", "ra_deg", "dec_deg", "epoch_mjd"}) {
    if (!col.count(need)) {
      throw InputError("known-object list '" + path + "': the header line has no column '" + need +
                       "' (needs name, ra_deg, dec_deg, epoch_mjd and ra/dec rates)");
    }
  }
  if (!arcsec && !degDay) {
    throw InputError("known-object list '" + path +
                     "': the header line names no rates (ra_rate_arcsec_min, dec_rate_arcsec_min or "
                     "ra_rate_deg_day, dec_rate_deg_day)");
  }
  const double rateScale = arcsec ? 1.0 : 3600.0 / (24.0 * 60.0);  // deg/day -> arcsec/min
  const std::string raRate = arcsec ? "ra_rate_arcsec_min" : "ra_rate_deg_day";
  const std::string decRate = arcsec ? "dec_rate_arcsec_min" : "dec_rate_deg_day";
  std::vector<KnownObject> out;
  while (std::getline(in, line)) {
    ++lineNo;
    if (trim(line).empty() || trim(line)[0] == '#') continue;
    const auto f = splitCsv(line);
    const std::string where = path + " line " + std::to_string(lineNo);
    auto field = [&](const std::string& name) -> const std::string& {
      const std::size_t i = col.at(name);
      if (i >= f.size()) throw InputError(where + ": no value in column '" + name + "'");
      return f[i];
    };
    KnownObject o;
    o.name = field("name");
    o.raDeg = parseNumber(field("ra_deg"), where + " column ra_deg");
    o.decDeg = parseNumber(field("dec_deg"), where + " column dec_deg");
    o.epochMjd = parseNumber(field("epoch_mjd"), where + " column epoch_mjd");
    o.raRateArcsecPerMin = rateScale * parseNumber(field(raRate), where + " column " + raRate);
    o.decRateArcsecPerMin = rateScale * parseNumber(field(decRate), where + " column " + decRate);
    if (std::abs(o.decDeg) > 90.0)
      throw InputError(where + ": dec_deg " + field("dec_deg") + " is beyond +-90");
    out.push_back(std::move(o));
  }
  return out;
}

SkyPosition propagate(const KnownObject& o, double mjd) noexcept {
  const double dtMin = (mjd - o.epochMjd) * 1440.0;
  SkyPosition p;
  p.decDeg = o.decDeg + o.decRateArcsecPerMin * dtMin / 3600.0;
  const double cosDec = std::max(1e-9, std::cos(0.5 * (o.decDeg + p.decDeg) * kDeg));
  p.raDeg = std::fmod(o.raDeg + o.raRateArcsecPerMin * dtMin / 3600.0 / cosDec, 360.0);
  if (p.raDeg < 0.0) p.raDeg += 360.0;
  return p;
}

double separationArcsec(double ra1, double dec1, double ra2, double dec2) noexcept {
  const double s1 = std::sin(0.5 * (dec2 - dec1) * kDeg), s2 = std::sin(0.5 * (ra2 - ra1) * kDeg);
  const double h = s1 * s1 + std::cos(dec1 * kDeg) * std::cos(dec2 * kDeg) * s2 * s2;
  return 2.0 * std::asin(std::min(1.0, std::sqrt(h))) / kDeg * 3600.0;
}

std::optional<KnownObjectMatch> matchKnownObject(const std::vector<KnownObject>& objects, double raDeg,
                                                 double decDeg, double mjd, double radiusArcsec) {
  std::optional<KnownObjectMatch> best;
  for (const auto& o : objects) {
    const SkyPosition p = propagate(o, mjd);
    const double d = separationArcsec(raDeg, decDeg, p.raDeg, p.decDeg);
    if (d <= radiusArcsec && (!best || d < best->separationArcsec)) best = KnownObjectMatch{&o, p, d};
  }
  return best;
}

ArtifactFlag knownObjectFlag(const std::vector<KnownObject>& objects, double raDeg, double decDeg, double mjd,
                             double radiusArcsec) {
  ArtifactFlag flag{ArtifactKind::KnownObject, false, -1.0, "no known-object list loaded"};
  if (objects.empty()) return flag;
  const KnownObject* nearest = nullptr;
  SkyPosition nearestAt;
  double dMin = 1e300;
  for (const auto& o : objects) {
    const SkyPosition p = propagate(o, mjd);
    const double d = separationArcsec(raDeg, decDeg, p.raDeg, p.decDeg);
    if (d < dMin) {
      dMin = d;
      nearest = &o;
      nearestAt = p;
    }
  }
  flag.value = dMin;
  flag.triggered = dMin <= radiusArcsec;
  char buf[512];
  std::snprintf(
      buf, sizeof buf,
      "nearest known object '%s' predicted at RA %.6f Dec %+.6f (propagated %.3f h from its epoch) is "
      "%.1f arcsec away; match radius %.1f arcsec",
      nearest->name.c_str(), nearestAt.raDeg, nearestAt.decDeg, (mjd - nearest->epochMjd) * 24.0, dMin,
      radiusArcsec);
  flag.evidence = buf;
  return flag;
}

}  // namespace st::vet

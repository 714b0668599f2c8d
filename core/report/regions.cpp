#include "st/report/regions.hpp"

#include <cctype>
#include <cmath>
#include <cstdio>
#include <fstream>

#include "st/common/error.hpp"
#include "st/io/wcs.hpp"

namespace st::report {
namespace {

std::string cleanText(const std::string& s) {
  std::string out;
  for (char c : s) {
    if (c != '{' && c != '}' && c != '"' && c != '\n') out += c;
  }
  return out;
}

std::string line(const char* fmt, auto... args) {
  char buf[512];
  std::snprintf(buf, sizeof buf, fmt, args...);
  return buf;
}

/// Local scale of the mapping at (x, y), arcsec per pixel (mean of the two axes).
double localScaleArcsec(const astro::PixelToSky& toSky, double x, double y) {
  const auto a = toSky(x - 0.5, y), b = toSky(x + 0.5, y), c = toSky(x, y - 0.5), d = toSky(x, y + 0.5);
  const double cosDec = std::cos(toSky(x, y).decDeg * M_PI / 180.0);
  auto sep = [&](const astro::SkyPoint& p, const astro::SkyPoint& q) {
    double dra = q.raDeg - p.raDeg;
    if (dra > 180.0) dra -= 360.0;
    if (dra < -180.0) dra += 360.0;
    return std::hypot(dra * cosDec, q.decDeg - p.decDeg) * 3600.0;
  };
  return 0.5 * (sep(a, b) + sep(c, d));
}

}  // namespace

std::string ds9SkyFrame(const Wcs& wcs) {
  const FitsHeader h = wcs.toHeader();
  std::string sys = h.getString("RADESYS").value_or("");
  for (auto& ch : sys)
    ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  sys.erase(sys.find_last_not_of(' ') + 1);
  if (sys == "icrs" || sys == "fk5" || sys == "fk4") return sys;
  if (!sys.empty()) return "fk5";
  const auto equinox = h.getDouble("EQUINOX");
  if (!equinox) return "icrs";
  return *equinox >= 1984.0 ? "fk5" : "fk4";
}

std::string ds9Regions(const std::vector<RegionMark>& marks, const astro::PixelToSky& toSky,
                       const std::string& skyFrame) {
  std::string out = "# Region file format: DS9 version 4.1\n# written by synthtrack; positions at t_ref\n";
  out +=
      "global color=green width=1 font=\"helvetica 10 normal roman\" select=1 edit=1 move=1 delete=1 "
      "include=1 source=1\n";
  out += toSky ? skyFrame + "\n" : "image\n";
  for (const auto& m : marks) {
    const std::string props =
        " # color=" + cleanText(m.color) + (m.text.empty() ? "" : " text={" + cleanText(m.text) + "}");
    if (toSky) {
      const auto p = toSky(m.x, m.y);
      const double r = m.radiusPx * localScaleArcsec(toSky, m.x, m.y);
      out += line("circle(%.7f,%+.7f,%.3f\")", p.raDeg, p.decDeg, r) + props + "\n";
    } else {
      out += line("circle(%.3f,%.3f,%.3f)", m.x + 1.0, m.y + 1.0, m.radiusPx) + props + "\n";
    }
    if (m.velocity) {
      // At time t the object is at (x, y) + v t on the detector, where the mapping of t_ref shows the sky of
      // (x, y) + (v - skyRate) t: on the sky the track is the motion relative to the stars.
      const Velocity u =
          toSky ? Velocity{m.velocity->vx - m.skyRate.vx, m.velocity->vy - m.skyRate.vy} : *m.velocity;
      const double x0 = m.x + u.vx * m.trackStartS, y0 = m.y + u.vy * m.trackStartS;
      const double x1 = m.x + u.vx * m.trackEndS, y1 = m.y + u.vy * m.trackEndS;
      const std::string lprops = " # line=0 1 color=" + cleanText(m.color);
      if (toSky) {
        const auto a = toSky(x0, y0), b = toSky(x1, y1);
        out += line("line(%.7f,%+.7f,%.7f,%+.7f)", a.raDeg, a.decDeg, b.raDeg, b.decDeg) + lprops + "\n";
      } else {
        out += line("line(%.3f,%.3f,%.3f,%.3f)", x0 + 1.0, y0 + 1.0, x1 + 1.0, y1 + 1.0) + lprops + "\n";
      }
    }
  }
  return out;
}

void writeDs9Regions(const std::string& path, const std::vector<RegionMark>& marks,
                     const astro::PixelToSky& toSky, const std::string& skyFrame) {
  const std::string text = ds9Regions(marks, toSky, skyFrame);
  std::ofstream out(path);
  if (!out) throw InputError("cannot write DS9 region file '" + path + "'");
  out << text;
  if (!out) throw InputError("error writing DS9 region file '" + path + "'");
}

astro::PixelToSky skyMappingAtTRef(const Wcs& wcs, Velocity skyRate, double mappingEpochOffsetS,
                                   PixelOffset mappingFrameOffset) {
  const double ox = mappingFrameOffset.x + skyRate.vx * mappingEpochOffsetS;
  const double oy = mappingFrameOffset.y + skyRate.vy * mappingEpochOffsetS;
  return [&wcs, ox, oy](double x, double y) {
    const auto s = wcs.pixelToSky(x + ox, y + oy);
    return astro::SkyPoint{s.raDeg, s.decDeg};
  };
}

astro::PixelToSky skyMappingAtTRef(const FrameCube& frames, Velocity skyRate) {
  const std::shared_ptr<const Wcs> wcs = frames.wcs;  // the mapping keeps it alive
  const FrameInfo& first = frames.info().front();
  const astro::PixelToSky atTRef =
      skyMappingAtTRef(*wcs, skyRate, frames.timeOffsetsS().front(), {first.offsetXPx, first.offsetYPx});
  return [wcs, atTRef](double x, double y) { return atTRef(x, y); };
}

}  // namespace st::report

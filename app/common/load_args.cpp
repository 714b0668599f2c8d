#include "load_args.hpp"

#include <cmath>
#include <cstdio>

#include "st/common/error.hpp"
#include "st/io/sections.hpp"

namespace st::app {

std::set<std::string> loadOptionNames() {
  return {"hdu", "start-mjd", "frame-rate", "exposure", "crop", "plate-scale"};
}

const char* loadOptionsHelp() {
  return "  --hdu H              image HDU: 1-based number (1 = primary) or EXTNAME (default: first with "
         "data)\n"
         "  --start-mjd M        mid-time (MJD UTC) of the first frame, for headers without times\n"
         "  --frame-rate HZ      frame rate, with --start-mjd\n"
         "  --exposure S         exposure (s) for headers without EXPTIME/EXPOSURE\n"
         "  --crop [x1:x2,y1:y2] crop every frame to this 1-based FITS section (frames of different sizes)\n"
         "  --plate-scale A      arcsec/px when there is no WCS\n";
}

io::LoadOptions loadOptionsFromArgs(const CliArgs& args) {
  io::LoadOptions o;
  if (auto h = args.value("hdu")) o.hdu = *h;
  o.startMjd = args.number("start-mjd");
  o.frameRateHz = args.number("frame-rate");
  o.exposureS = args.number("exposure");
  o.plateScaleArcsecPerPx = args.number("plate-scale");
  if (o.startMjd.has_value() != o.frameRateHz.has_value()) {
    throw UsageError("--start-mjd and --frame-rate go together");
  }
  if (o.frameRateHz && !(*o.frameRateHz > 0.0)) throw UsageError("--frame-rate must be > 0");
  if (auto c = args.value("crop")) {
    try {
      o.crop = io::parseSection(*c, "--crop");
    } catch (const InputError& e) {
      throw UsageError(e.what());
    }
  }
  return o;
}

std::set<std::string> calibFlagNames() {
  return {"no-overscan", "ignore-sections"};
}

const char* calibOptionsHelp() {
  return "  --no-overscan        do not subtract the overscan (BIASSEC)\n"
         "  --ignore-sections    ignore the headers' BIASSEC, TRIMSEC and DATASEC (no overscan, no trim);\n"
         "                       without it, a section that does not fit the frames is clipped to them\n";
}

calib::CalibParams calibParamsFromArgs(const CliArgs& args) {
  calib::CalibParams p;
  if (args.flag("no-overscan")) p.subtractOverscan = false;
  if (args.flag("ignore-sections")) p.useHeaderSections = false;
  return p;
}

void printWarnings(const std::vector<std::string>& warnings) {
  bool section = false;
  for (const auto& w : warnings) {
    std::fprintf(stderr, "warning: %s\n", w.c_str());
    for (std::string_view key : io::kImageSectionKeywords)
      section = section || w.find(key) != std::string::npos;
  }
  if (section) {
    std::fprintf(stderr,
                 "hint: --no-overscan skips the overscan, --ignore-sections ignores the headers' image "
                 "sections\n");
  }
}

std::string isoFromMjd(double mjd) {
  const double dayFloor = std::floor(mjd);
  long jdn = static_cast<long>(dayFloor) + 2400001;  // Julian Day Number of the civil date
  // Richards (2013) inverse of the Gregorian calendar.
  const long f = jdn + 1401 + (((4 * jdn + 274277) / 146097) * 3) / 4 - 38;
  const long e = 4 * f + 3;
  const long g = (e % 1461) / 4;
  const long h = 5 * g + 2;
  const int day = static_cast<int>((h % 153) / 5 + 1);
  const int month = static_cast<int>((h / 153 + 2) % 12 + 1);
  const long year = e / 1461 - 4716 + (12 + 2 - month) / 12;
  double secs = (mjd - dayFloor) * 86400.0;
  secs = std::round(secs * 1000.0) / 1000.0;
  const int hh = static_cast<int>(secs / 3600);
  const int mm = static_cast<int>((secs - hh * 3600) / 60);
  const double ss = secs - hh * 3600 - mm * 60;
  char buf[64];
  std::snprintf(buf, sizeof buf, "%04ld-%02d-%02dT%02d:%02d:%06.3f", year, month, day, hh, mm, ss);
  return buf;
}

}  // namespace st::app

#include "plate_solve_args.hpp"

#include <cmath>

namespace st::app {

std::set<std::string> plateSolveOptionNames() {
  return {"solve-scale",      "solve-ra",    "solve-dec", "solve-radius",
          "solve-time-limit", "solve-stars", "index-dir", "solve-field"};
}

std::set<std::string> plateSolveFlagNames() {
  return {"keep-solve-files"};
}

const char* plateSolveOptionsHelp() {
  return "plate solving (astrometry.net's solve-field; Debian packages astrometry.net and\n"
         "astrometry-data-tycho2-NN-littleendian, installed by scripts/install-deps.sh):\n"
         "  --solve-scale A         plate-scale hint, arcsec/px (default: the header's SECPIX/PIXSCALE/...;\n"
         "                          searched within a factor 1.3; none: 0.1-100 arcsec/px)\n"
         "  --solve-ra DEG --solve-dec DEG   pointing hint (default: the header's RA/DEC, OBJCTRA/OBJCTDEC)\n"
         "  --solve-radius DEG      search radius around the pointing hint (default 2)\n"
         "  --solve-time-limit S    give up after S seconds (default 120)\n"
         "  --solve-stars N         brightest stars given to solve-field (default 300)\n"
         "  --index-dir DIR         folder of index files (repeatable; default: /etc/astrometry.cfg's)\n"
         "  --solve-field PROGRAM   the solve-field to run (default: solve-field on PATH)\n"
         "  --keep-solve-files      keep solve-field's work folder (printed) for inspection\n";
}

astro::PlateSolveParams plateSolveParamsFromArgs(const CliArgs& args) {
  astro::PlateSolveParams p;
  auto positive = [&](const char* name) -> std::optional<double> {
    const auto v = args.number(name);
    if (v && !(*v > 0.0 && std::isfinite(*v))) throw UsageError(std::string("--") + name + " must be > 0");
    return v;
  };
  p.scaleArcsecPerPx = positive("solve-scale");
  if (args.has("solve-ra") != args.has("solve-dec"))
    throw UsageError("give --solve-ra and --solve-dec together");
  p.raDeg = args.number("solve-ra");
  p.decDeg = args.number("solve-dec");
  if (p.raDeg && !(*p.raDeg >= 0.0 && *p.raDeg < 360.0))
    throw UsageError("--solve-ra must be in [0, 360) deg");
  if (p.decDeg && !(std::abs(*p.decDeg) <= 90.0)) throw UsageError("--solve-dec must be in [-90, 90] deg");
  if (const auto r = positive("solve-radius")) p.radiusDeg = *r;
  if (const auto t = positive("solve-time-limit")) p.timeLimitS = *t;
  if (const auto n = args.integer("solve-stars")) {
    if (*n < 4) throw UsageError("--solve-stars must be >= 4");
    p.maxStars = static_cast<std::size_t>(*n);
  }
  p.indexDirs = args.values("index-dir");
  if (const auto s = args.value("solve-field")) p.solveField = *s;
  p.keepWorkDir = args.flag("keep-solve-files");
  return p;
}

}  // namespace st::app

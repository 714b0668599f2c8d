// synthtrack-cli solve FILE... [--wcs-dir DIR] [--json]: plate-solves each file's first frame with
// astrometry.net (issue 15 item 5) from the sources found in it, prints the solution and, when the file has a
// WCS of its own, how far the two are apart at the centre and the corners.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "cli_args.hpp"
#include "commands.hpp"
#include "load_args.hpp"
#include "plate_solve_args.hpp"
#include "st/common/error.hpp"
#include "st/io/fits_reader.hpp"
#include "st/io/wcs.hpp"
#include "st/io/xylist.hpp"
#include "st/pipeline/plate_solve_stage.hpp"
#include "terminal_progress.hpp"

namespace st::app {
namespace {

const char* kHelp =
    "usage: synthtrack-cli solve FILE... [options]\n\n"
    "Plate-solves the first frame of each FILE: the sources found in it (brightest first) go to\n"
    "astrometry.net's solve-field, whose WCS is printed (centre, scale) and, with --wcs-dir, written as\n"
    "DIR/<file>.wcs (a header-only FITS file). A header WCS is ignored for the solve and compared with the\n"
    "solution (arcsec at the centre and the four corners). `preprocess --plate-solve` solves the first frame\n"
    "the same way (the pre-processed star catalogue when that fails) and writes the WCS into its outputs.\n\n"
    "  --wcs-dir DIR           write each solution to DIR/<file name>.wcs\n"
    "  --json                  JSON output\n";

/// Great-circle distance, arcsec.
double separationArcsec(const Wcs::Sky& a, const Wcs::Sky& b) {
  constexpr double d = M_PI / 180.0;
  const double s = std::sin(a.decDeg * d) * std::sin(b.decDeg * d) +
                   std::cos(a.decDeg * d) * std::cos(b.decDeg * d) * std::cos((a.raDeg - b.raDeg) * d);
  return std::acos(std::clamp(s, -1.0, 1.0)) / d * 3600.0;
}

nlohmann::json solveOne(const std::string& file, const io::LoadOptions& load,
                        const astro::PlateSolveParams& params, const CliArgs& cli) {
  TerminalProgress progress;
  CancelToken& cancel = processCancelToken();
  FrameCube cube = io::loadFrames({file}, load, progress, cancel);
  const std::shared_ptr<const Wcs> headerWcs = cube.wcs;
  cube.wcs.reset();  // solved from the pixels alone; the header's WCS is only compared with
  if (headerWcs) cube.plateScaleArcsecPerPx.reset();
  const std::vector<io::XyStar> stars = pipeline::frameStars(cube, progress, cancel);
  const astro::PlateSolution s = pipeline::plateSolveCube(cube, stars, params, progress, cancel);
  progress.finish();
  nlohmann::json j;
  j["file"] = file;
  j["stars_found"] = stars.size();
  j["stars_given"] = s.starsGiven;
  j["ra_deg"] = s.centreRaDeg;
  j["dec_deg"] = s.centreDecDeg;
  j["scale_arcsec_px"] = s.scaleArcsecPerPx;
  j["index"] = s.index;
  j["method"] = s.method;
  j["elapsed_s"] = s.elapsedS;
  if (!s.workDir.empty()) j["work_dir"] = s.workDir;
  if (headerWcs) {
    const double w = cube.width() - 1.0, h = cube.height() - 1.0;
    const double points[5][2] = {{0.5 * w, 0.5 * h}, {0, 0}, {w, 0}, {0, h}, {w, h}};
    nlohmann::json diffs = nlohmann::json::array();
    for (const auto& p : points)
      diffs.push_back(separationArcsec(headerWcs->pixelToSky(p[0], p[1]), s.wcs->pixelToSky(p[0], p[1])));
    j["header_wcs_diff_arcsec"] = {{"centre", diffs[0]},
                                   {"corners", {diffs[1], diffs[2], diffs[3], diffs[4]}}};
    // Where the solution's centre lies in the header WCS's pixels, relative to the centre (px).
    const Wcs::Sky c = s.wcs->pixelToSky(0.5 * w, 0.5 * h);
    const auto [hx, hy] = headerWcs->skyToPixel(c.raDeg, c.decDeg);
    j["header_wcs_centre_offset_px"] = {hx - 0.5 * w, hy - 0.5 * h};
  }
  if (const auto dir = cli.value("wcs-dir")) {
    std::filesystem::create_directories(*dir);
    std::string name = std::filesystem::path(file).filename().string();
    for (const char* ext : {".fz", ".gz", ".fits", ".fit", ".fts"})
      if (name.size() > std::strlen(ext) &&
          name.compare(name.size() - std::strlen(ext), std::string::npos, ext) == 0)
        name.resize(name.size() - std::strlen(ext));
    const std::string out = (std::filesystem::path(*dir) / (name + ".wcs")).string();
    io::writeHeaderFile(out, s.header);
    j["wcs_file"] = out;
  }
  return j;
}

}  // namespace

int cmdSolve(const Args& args) {
  if (!args.empty() && args[0] == "--help") {
    std::printf("%s%s%s", kHelp, plateSolveOptionsHelp(), loadOptionsHelp());
    return 0;
  }
  auto names = loadOptionNames();
  for (const auto& n : plateSolveOptionNames())
    names.insert(n);
  names.insert("wcs-dir");
  auto flags = plateSolveFlagNames();
  flags.insert("json");
  const CliArgs cli(args, names, flags);
  if (cli.positionals().empty()) throw UsageError("give at least one FITS file to plate-solve");
  const io::LoadOptions load = loadOptionsFromArgs(cli);
  const astro::PlateSolveParams params = plateSolveParamsFromArgs(cli);
  nlohmann::json all = nlohmann::json::array();
  for (const auto& file : cli.positionals()) {
    const nlohmann::json j = solveOne(file, load, params, cli);
    all.push_back(j);
    if (cli.flag("json")) continue;
    std::printf(
        "%s: RA %.6f Dec %+.6f deg at the centre, %.4f arcsec/px, %s (%s), %zu of %zu stars given, %.1f s\n",
        file.c_str(), j["ra_deg"].get<double>(), j["dec_deg"].get<double>(),
        j["scale_arcsec_px"].get<double>(),
        j["index"].get<std::string>().empty() ? "index not named" : j["index"].get<std::string>().c_str(),
        j["method"].get<std::string>().c_str(), j["stars_given"].get<std::size_t>(),
        j["stars_found"].get<std::size_t>(), j["elapsed_s"].get<double>());
    if (j.contains("header_wcs_diff_arcsec")) {
      const auto& d = j["header_wcs_diff_arcsec"];
      std::printf("  header WCS vs solution: %.3f arcsec at the centre; corners %.3f %.3f %.3f %.3f arcsec\n",
                  d["centre"].get<double>(), d["corners"][0].get<double>(), d["corners"][1].get<double>(),
                  d["corners"][2].get<double>(), d["corners"][3].get<double>());
      std::printf("  the solution's centre in the header WCS's pixels: (%+.3f, %+.3f) px from the centre\n",
                  j["header_wcs_centre_offset_px"][0].get<double>(),
                  j["header_wcs_centre_offset_px"][1].get<double>());
    }
    if (j.contains("wcs_file")) std::printf("  wrote %s\n", j["wcs_file"].get<std::string>().c_str());
    if (j.contains("work_dir"))
      std::printf("  solve-field's files: %s\n", j["work_dir"].get<std::string>().c_str());
  }
  if (cli.flag("json")) std::printf("%s\n", all.dump(2).c_str());
  return 0;
}

}  // namespace st::app

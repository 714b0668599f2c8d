#include "field_index.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <tuple>

#include "child_process.hpp"
#include "st/common/error.hpp"
#include "st/io/xylist.hpp"

namespace st::astro::detail {
namespace {

std::string num(double v) {
  char b[64];
  std::snprintf(b, sizeof b, "%.10g", v);
  return b;
}

/// The magnitude column of query-starkd's table (tycho2: MAG_VT, MAG_BT, MAG), or empty.
std::string magnitudeColumn(const std::string& table) {
  const FitsHeader h = io::readFitsHeader(table, 2);
  std::string first;
  for (const auto& c : h.cards) {
    if (c.key.rfind("TTYPE", 0) != 0) continue;
    std::string name = c.value;
    while (!name.empty() && name.back() == ' ')
      name.pop_back();
    if (name == "MAG_VT") return name;
    if (first.empty() && name.rfind("MAG", 0) == 0) first = name;
  }
  return first;
}

long long rowCount(const std::string& table) {
  const FitsHeader h = io::readFitsHeader(table, 2);
  const auto n = h.getDouble("NAXIS2");
  return n ? static_cast<long long>(*n) : 0;
}

bool runQuiet(const std::vector<std::string>& argv, const std::string& dir, const std::string& name,
              ProgressSink& progress, CancelToken& cancel, std::string& why) {
  const ChildResult r = runChild(argv, dir + "/" + name + ".out", dir + "/" + name + ".err", 60.0, progress,
                                 cancel, "plate solving: field index");
  if (r.exitCode == 0 && !r.timedOut) return true;
  why = argv[0] + " failed (exit " + std::to_string(r.exitCode) +
        "): " + tailOfFile(dir + "/" + name + ".err", 4);
  return false;
}

}  // namespace

std::string buildFieldIndexes(const PlateSolveParams& params, const std::vector<IndexFile>& installed,
                              double sideArcmin, double diagonalArcmin, const std::string& dir,
                              ProgressSink& progress, CancelToken& cancel, std::string& why) {
  if (!params.raDeg || !params.decDeg) {
    why = "no pointing hint";
    return {};
  }
  const std::string query = findProgram("query-starkd");
  const std::string build = findProgram("build-astrometry-index");
  if (query.empty() || build.empty()) {
    why = "query-starkd or build-astrometry-index not found";
    return {};
  }
  if (installed.empty()) {
    why = "no index files";
    return {};
  }
  const IndexFile source = *std::min_element(installed.begin(), installed.end(),
                                             [](const auto& a, const auto& b) { return a.scale < b.scale; });
  const std::string region = dir + "/field-stars.fits";
  const double radius = params.radiusDeg + 0.5 * diagonalArcmin / 60.0;
  if (!runQuiet({query, "-r", num(*params.raDeg), "-d", num(*params.decDeg), "-R", num(radius), "-T", "-o",
                 region, source.path},
                dir, "query-starkd", progress, cancel, why))
    return {};
  if (rowCount(region) < 5) {
    why = "fewer than 5 catalogue stars around the pointing hint";
    return {};
  }
  const std::string mag = magnitudeColumn(region);
  const std::string out = dir + "/field-index";
  std::filesystem::create_directories(out);
  int built = 0;
  for (int scale = 0; scale <= 19; ++scale) {
    // astrometry.net's scale numbers (plate_solve_hints.cpp): quads from 25% of the side to the diagonal.
    IndexFile probe;
    probe.scale = scale;
    std::tie(probe.quadMinArcmin, probe.quadMaxArcmin) = quadSizeArcmin(scale);
    if (!indexSuitsField(probe, 2.5 * sideArcmin, diagonalArcmin)) continue;
    char name[64];
    std::snprintf(name, sizeof name, "index-99%02d.fits", scale);
    std::vector<std::string> argv = {build,
                                     "-i",
                                     region,
                                     "-e",
                                     "1",
                                     "-o",
                                     out + "/" + name,
                                     "-P",
                                     std::to_string(scale),
                                     "-E",
                                     "-M",
                                     "-d",
                                     "3",
                                     "-p",
                                     "64",
                                     "-R",
                                     "64",
                                     "-I",
                                     std::to_string(990000 + scale),
                                     "-t",
                                     dir};
    if (!mag.empty()) argv.insert(argv.end(), {"-S", mag});
    if (!runQuiet(argv, dir, "build-index-" + std::to_string(scale), progress, cancel, why)) return {};
    ++built;
  }
  if (built == 0) {
    why = "no quad scale suits the field";
    return {};
  }
  return out;
}

}  // namespace st::astro::detail

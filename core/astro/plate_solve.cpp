#include "st/astro/plate_solve.hpp"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "child_process.hpp"
#include "field_index.hpp"
#include "st/common/error.hpp"
#include "st/io/wcs.hpp"

namespace st::astro {
namespace {

constexpr const char* kDefaultConfig = "/etc/astrometry.cfg";
constexpr const char* kInstallHint =
    "install the Debian package astrometry.net and an index package for the field size, e.g. "
    "astrometry-data-tycho2-07-littleendian for fields of about 22'-30' (scripts/install-deps.sh installs "
    "both)";

std::string fmt(double v, int digits = 4) {
  char b[64];
  std::snprintf(b, sizeof b, "%.*g", digits, v);
  return b;
}

/// A fresh folder under the system's temporary folder, removed on destruction unless kept.
class WorkDir {
 public:
  WorkDir() {
    std::string pattern = (std::filesystem::temp_directory_path() / "synthtrack-solve-XXXXXX").string();
    if (::mkdtemp(pattern.data()) == nullptr)
      throw InputError("cannot create a temporary folder for solve-field");
    m_path = pattern;
  }
  ~WorkDir() {
    if (m_keep) return;
    std::error_code ec;
    std::filesystem::remove_all(m_path, ec);
  }
  WorkDir(const WorkDir&) = delete;
  WorkDir& operator=(const WorkDir&) = delete;
  [[nodiscard]] const std::string& path() const { return m_path; }
  [[nodiscard]] std::string file(const std::string& name) const { return m_path + "/" + name; }
  void keep() { m_keep = true; }

 private:
  std::string m_path;
  bool m_keep = false;
};

std::string describeIndexes(const std::vector<IndexFile>& indexes) {
  std::string out;
  for (const auto& i : indexes)
    out += (out.empty() ? "" : ", ") + std::filesystem::path(i.path).filename().string() + " (" +
           fmt(i.quadMinArcmin) + "'-" + fmt(i.quadMaxArcmin) + "')";
  return out;
}

std::string joinDirs(const std::vector<std::string>& dirs) {
  std::string out;
  for (const auto& d : dirs)
    out += (out.empty() ? "" : ", ") + d;
  return out.empty() ? std::string("(none)") : out;
}

/// Throws when no index file is installed, or none suits the field size implied by the scale hint.
void checkIndexes(const PlateSolveParams& p, const std::vector<IndexFile>& indexes, int width, int height,
                  const std::string& before) {
  if (!p.scaleArcsecPerPx) return;  // the field size is unknown: solve-field tries them all
  const double side = std::max(width, height) * *p.scaleArcsecPerPx / 60.0;
  const double diagonal = std::hypot(width, height) * *p.scaleArcsecPerPx / 60.0;
  for (const auto& i : indexes)
    if (indexSuitsField(i, side / p.scaleTolerance, diagonal * p.scaleTolerance)) return;
  const std::vector<std::string> packages = indexPackagesFor(side);
  std::string advice;
  if (packages.empty()) {
    advice =
        "the Tycho-2 index packages start at quads of 22', too large for this field: index files of a "
        "deeper catalogue (astrometry.net's 4200 or 5200 series for quads of " +
        fmt(0.1 * side, 2) + "'-" + fmt(diagonal, 2) + "') must be put in a folder given as the index folder";
  } else {
    advice = "install";
    for (const auto& pkg : packages)
      advice += " " + pkg;
  }
  throw InputError("plate solving: no index file suits a field of " + fmt(side, 3) + "' (" +
                   std::to_string(width) + " x " + std::to_string(height) + " px at about " +
                   fmt(*p.scaleArcsecPerPx) + " arcsec/px; quads of " + fmt(0.1 * side, 2) + "'-" +
                   fmt(diagonal, 3) + "' are needed); installed: " + describeIndexes(indexes) + "; " +
                   advice + before);
}

std::vector<std::string> solveFieldArgs(const std::string& program, const PlateSolveParams& p,
                                        const WorkDir& dir, const std::string& config,
                                        const std::string& prefix, int width, int height, double timeLimitS,
                                        std::optional<double> oddsToSolve) {
  const int limit = std::max(1, static_cast<int>(std::ceil(timeLimitS)));
  std::vector<std::string> a = {program,
                                "--overwrite",
                                "--no-plots",
                                "--no-remove-lines",
                                "--uniformize",
                                "0",
                                "--x-column",
                                io::kXylistXColumn,
                                "--y-column",
                                io::kXylistYColumn,
                                "--sort-column",
                                io::kXylistFluxColumn,
                                "--width",
                                std::to_string(width),
                                "--height",
                                std::to_string(height),
                                "--crpix-center",
                                "--tweak-order",
                                std::to_string(p.tweakOrder),
                                "--cpulimit",
                                std::to_string(limit),
                                "--dir",
                                dir.path(),
                                "--temp-dir",
                                dir.path(),
                                "--out",
                                prefix,
                                "--new-fits",
                                "none",
                                "--corr",
                                "none",
                                "--rdls",
                                "none",
                                "--match",
                                "none",
                                "--index-xyls",
                                "none",
                                "--scale-units",
                                "arcsecperpix"};
  double lo = p.wideScaleLowArcsecPerPx, hi = p.wideScaleHighArcsecPerPx;
  if (p.scaleArcsecPerPx) {
    lo = *p.scaleArcsecPerPx / p.scaleTolerance;
    hi = *p.scaleArcsecPerPx * p.scaleTolerance;
  }
  a.insert(a.end(), {"--scale-low", fmt(lo, 8), "--scale-high", fmt(hi, 8)});
  if (p.raDeg && p.decDeg)
    a.insert(a.end(),
             {"--ra", fmt(*p.raDeg, 10), "--dec", fmt(*p.decDeg, 10), "--radius", fmt(p.radiusDeg, 6)});
  if (!config.empty()) a.insert(a.end(), {"--config", config});
  if (oddsToSolve) a.insert(a.end(), {"--odds-to-solve", fmt(*oddsToSolve, 6)});
  a.push_back(dir.file("stars.xyls"));
  return a;
}

/// "solved with index index-tycho2-07.littleendian.fits." in solve-field's stdout.
std::string solvingIndex(const std::string& log) {
  const std::string marker = "solved with index ";
  const auto at = log.find(marker);
  if (at == std::string::npos) return {};
  auto end = log.find_first_of("\n", at);
  std::string name =
      log.substr(at + marker.size(), end == std::string::npos ? std::string::npos : end - at - marker.size());
  while (!name.empty() && (name.back() == '.' || name.back() == ' ' || name.back() == '\r'))
    name.pop_back();
  return name;
}

std::string readAll(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string hintText(const PlateSolveParams& p) {
  std::string t = p.scaleArcsecPerPx ? "scale " + fmt(*p.scaleArcsecPerPx / p.scaleTolerance) + "-" +
                                           fmt(*p.scaleArcsecPerPx * p.scaleTolerance) + " arcsec/px"
                                     : "scale " + fmt(p.wideScaleLowArcsecPerPx) + "-" +
                                           fmt(p.wideScaleHighArcsecPerPx) + " arcsec/px (no hint)";
  if (p.raDeg && p.decDeg)
    t += ", within " + fmt(p.radiusDeg) + " deg of RA " + fmt(*p.raDeg, 8) + " Dec " + fmt(*p.decDeg, 7);
  return t;
}

/// Writes a configuration listing `dirs` (add_path) into the work folder; returns its path.
std::string writeConfig(const WorkDir& dir, const std::string& name, const std::vector<std::string>& dirs) {
  const std::string path = dir.file(name);
  std::ofstream cfg(path);
  for (const auto& d : dirs)
    cfg << "add_path " << d << "\n";
  cfg << "autoindex\n";
  return path;
}

struct Attempt {
  detail::ChildResult run;
  std::string prefix;  ///< solve-field's --out
  bool solved = false;
};

Attempt runSolveField(const std::string& program, const PlateSolveParams& p, const WorkDir& dir,
                      const std::string& config, const std::string& prefix, int width, int height,
                      double limitS, std::optional<double> odds, ProgressSink& progress,
                      CancelToken& cancel) {
  auto argv = solveFieldArgs(program, p, dir, config, prefix, width, height, limitS, odds);
  Attempt a;
  a.prefix = prefix;
  a.run = detail::runChild(argv, dir.file(prefix + ".stdout"), dir.file(prefix + ".stderr"), limitS, progress,
                           cancel, "plate solving");
  std::error_code ec;
  a.solved = !a.run.timedOut && a.run.exitCode == 0 &&
             std::filesystem::exists(dir.file(prefix + ".solved"), ec) &&
             std::filesystem::exists(dir.file(prefix + ".wcs"), ec);
  return a;
}

PlateSolution readSolution(const WorkDir& dir, const Attempt& a, int width, int height) {
  PlateSolution out;
  out.log = readAll(dir.file(a.prefix + ".stdout"));
  out.header = io::readFitsHeader(dir.file(a.prefix + ".wcs"));
  std::vector<std::string> warnings;
  out.wcs = Wcs::fromHeader(out.header, &warnings);
  if (!out.wcs) {
    std::string w;
    for (const auto& s : warnings)
      w += "; " + s;
    throw InputError("plate solving: solve-field's WCS could not be read" + w);
  }
  out.scaleArcsecPerPx = out.wcs->plateScaleArcsecPerPx();
  const Wcs::Sky centre = out.wcs->pixelToSky(0.5 * (width - 1), 0.5 * (height - 1));
  out.centreRaDeg = centre.raDeg;
  out.centreDecDeg = centre.decDeg;
  out.index = solvingIndex(out.log);
  return out;
}

}  // namespace

PlateSolution plateSolve(const std::vector<io::XyStar>& stars, int width, int height,
                         const PlateSolveParams& params, ProgressSink& progress, CancelToken& cancel) {
  if (!(params.timeLimitS > 0.0)) throw InputError("plate solving: the time limit must be > 0 s");
  if (params.scaleArcsecPerPx && !(*params.scaleArcsecPerPx > 0.0))
    throw InputError("plate solving: the scale hint must be > 0 arcsec/px, got " +
                     fmt(*params.scaleArcsecPerPx));
  if (width <= 0 || height <= 0) throw InputError("plate solving: the frame size must be positive");
  const std::string program = detail::findProgram(params.solveField);
  if (program.empty())
    throw InputError("plate solving needs astrometry.net's solve-field, which was not found (looked for '" +
                     params.solveField + "' on PATH): " + kInstallHint);
  const std::string config = params.configPath.empty() ? std::string(kDefaultConfig) : params.configPath;
  const std::vector<std::string> dirs = params.indexDirs.empty() ? configIndexDirs(config) : params.indexDirs;
  const std::vector<IndexFile> indexes = findIndexFiles(dirs);
  if (indexes.empty())
    throw InputError("plate solving: no astrometry.net index files (index-*.fits) in " + joinDirs(dirs) +
                     ": " + kInstallHint);

  std::vector<io::XyStar> usable;
  for (const auto& s : stars)
    if (std::isfinite(s.x) && std::isfinite(s.y) && std::isfinite(s.flux)) usable.push_back(s);
  if (usable.size() < 4)
    throw InputError("plate solving needs at least 4 stars, got " + std::to_string(usable.size()));
  std::stable_sort(usable.begin(), usable.end(),
                   [](const auto& a, const auto& b) { return a.flux > b.flux; });
  if (usable.size() > params.maxStars) usable.resize(std::max<std::size_t>(params.maxStars, 4));

  WorkDir dir;
  if (params.keepWorkDir) dir.keep();
  io::writeXylist(dir.file("stars.xyls"), usable, width, height);
  const auto start = std::chrono::steady_clock::now();
  auto remaining = [&] {
    return params.timeLimitS -
           std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  const std::string what = std::to_string(usable.size()) + " stars, " + hintText(params);
  auto finish = [&](const Attempt& a, const std::string& how) {
    PlateSolution out = readSolution(dir, a, width, height);
    out.starsGiven = usable.size();
    out.elapsedS = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    out.method = how;
    if (params.keepWorkDir) out.workDir = dir.path();
    progress.report(1.0, "plate solving");
    return out;
  };

  // 1. Index files of this field's own scales, from the installed stars around the pointing hint.
  std::string before;
  if (params.fieldIndex && params.scaleArcsecPerPx && params.raDeg && params.decDeg) {
    const double side = std::max(width, height) * *params.scaleArcsecPerPx / 60.0;
    const double diagonal = std::hypot(width, height) * *params.scaleArcsecPerPx / 60.0;
    std::string why;
    const std::string folder =
        detail::buildFieldIndexes(params, indexes, side / params.scaleTolerance,
                                  diagonal * params.scaleTolerance, dir.path(), progress, cancel, why);
    if (!folder.empty()) {
      PlateSolveParams linear = params;
      linear.tweakOrder = 1;
      const Attempt a =
          runSolveField(program, linear, dir, writeConfig(dir, "field.cfg", {folder}), "field", width, height,
                        std::max(1.0, 0.5 * remaining()), params.fieldIndexOddsToSolve, progress, cancel);
      if (a.solved) return finish(a, "field index (3-star quads from the installed index stars)");
      before = a.run.timedOut ? "; the field's own index found nothing within its half of the time limit"
                              : "; the field's own index found nothing";
    } else {
      before = "; no field index (" + why + ")";
    }
  }

  // 2. The installed index files.
  checkIndexes(params, indexes, width, height, before);
  if (remaining() < 1.0)
    throw InputError("plate solving: no solution within the time limit of " + fmt(params.timeLimitS) +
                     " s (" + what + before + ")");
  const std::string ownConfig =
      !params.indexDirs.empty() ? writeConfig(dir, "installed.cfg", params.indexDirs) : params.configPath;
  const Attempt a = runSolveField(program, params, dir, ownConfig, "installed", width, height, remaining(),
                                  std::nullopt, progress, cancel);
  if (a.solved) return finish(a, "installed index files");
  const std::string full = what + ", index files in " + joinDirs(dirs) + before;
  if (a.run.timedOut)
    throw InputError("plate solving: no solution within the time limit of " + fmt(params.timeLimitS) +
                     " s (" + full + "); allow more time, or check the scale and pointing hints");
  if (a.run.exitCode != 0) {
    std::string err = detail::tailOfFile(dir.file("installed.stderr"), 12);
    if (err.empty()) err = detail::tailOfFile(dir.file("installed.stdout"), 12);
    throw InputError("plate solving: solve-field failed (exit " + std::to_string(a.run.exitCode) +
                     "): " + err);
  }
  const std::string err = detail::tailOfFile(dir.file("installed.stderr"), 6);
  throw InputError("plate solving: astrometry.net found no solution (" + full +
                   (err.empty() ? std::string{} : "; solve-field said: " + err) +
                   "); check the scale and pointing hints, or install index files for the field size");
}

}  // namespace st::astro

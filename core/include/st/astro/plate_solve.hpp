#pragma once
// Plate solving: the WCS of frames that have none (raw frames often; the simulator's first demo), found by
// astrometry.net's `solve-field` (Debian package astrometry.net, index files astrometry-data-tycho2-*) run
// as an external process on a star list we already have (the pre-processing's static-source catalogue, or
// the sources of one frame). The star list goes to solve-field as an "xylist" FITS table
// (io/xylist.hpp, 1-based), the solved WCS comes back as a header-only FITS file read by st::Wcs (wcslib),
// so it maps 0-based pixels like a header WCS (ARCHITECTURE.md, pixels).
//
// solve-field runs without a shell (posix_spawnp with an argument vector: no string is ever interpreted),
// in its own process group in a temporary folder, under a wall-clock time limit (also passed to it as
// --cpulimit); a cancel or the limit stops the whole group (SIGTERM, then SIGKILL). Its stdout and stderr
// are kept for the error messages.
#include <cstddef>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "st/common/fits_header.hpp"
#include "st/common/progress.hpp"
#include "st/io/xylist.hpp"

namespace st {
class Wcs;
}

namespace st::astro {

struct PlateSolveParams {
  /// solve-field: a program name looked up on PATH, or a path.
  std::string solveField = "solve-field";
  /// Plate-scale hint, arcsec/px (header or user); solve-field searches [hint / scaleTolerance,
  /// hint * scaleTolerance]. None: the wide range below. The tolerance is wide because header scales are
  /// often nominal: the Lowell 42" frames say 0.981 (SECPIXX) where the solution is 1.107 arcsec/px.
  std::optional<double> scaleArcsecPerPx;
  double scaleTolerance = 1.3;
  double wideScaleLowArcsecPerPx = 0.1;
  double wideScaleHighArcsecPerPx = 100.0;
  /// Pointing hint (header RA/DEC or user), ICRS degrees: solutions are looked for within radiusDeg of it.
  std::optional<double> raDeg;
  std::optional<double> decDeg;
  double radiusDeg = 2.0;
  /// Wall-clock limit, seconds (also solve-field's --cpulimit).
  double timeLimitS = 120.0;
  /// The brightest maxStars stars are written to the xylist.
  std::size_t maxStars = 300;
  /// SIP distortion order of the solution (solve-field --tweak-order) from the installed index files. The
  /// field-index attempt fits order 1 (no SIP): it matches only a handful of stars.
  int tweakOrder = 2;
  /// astrometry.net configuration (add_path/index lines); empty = /etc/astrometry.cfg.
  std::string configPath;
  /// Folders of index files; when given, a configuration listing only these is written and used instead
  /// of configPath.
  std::vector<std::string> indexDirs;
  /// First try index files made for this field (astro/field_index.hpp): 3-star quads at the field's own
  /// scales, built from the installed index stars within radiusDeg of the pointing hint; needs the scale and
  /// pointing hints. It gets half the time limit; the installed index files the rest.
  bool fieldIndex = true;
  /// solve-field's --odds-to-solve for that attempt. Default astrometry.net's 1e9 asks more matched stars
  /// than a small field holds of Tycho-2 (the Lowell frames' right solution: log-odds 14.5-16.2 from 5 of
  /// 6 index stars); the pointing and scale constraints stand in for the rest.
  double fieldIndexOddsToSolve = 1e6;
  /// Keep solve-field's work folder (its logs, xylist and .wcs) instead of removing it; its path is in
  /// PlateSolution::workDir.
  bool keepWorkDir = false;
};

/// Hints that a header without a WCS still gives.
struct PlateSolveHints {
  std::optional<double> scaleArcsecPerPx;
  std::string scaleSource;  ///< the keywords, e.g. "SECPIXX"
  std::optional<double> raDeg;
  std::optional<double> decDeg;
  std::string pointingSource;  ///< e.g. "RA/DEC"
};

/// Reads the hints from `header`: scale from SECPIX, SECPIXX(/Y), PIXSCALE, PIXSCAL1, SCALE, or PIXSCAL
/// times the binning (CCDSUM, XBINNING); pointing from RA/DEC, OBJCTRA/OBJCTDEC, TELRA/TELDEC, as degrees
/// or sexagesimal (RA in hours when written h:m:s). Values that cannot be read are skipped, never thrown.
PlateSolveHints plateSolveHints(const FitsHeader& header);

/// Copies the hints into params where params has none.
void applyHints(PlateSolveParams& params, const PlateSolveHints& hints);

/// One astrometry.net index file and the sizes of the star quads it holds (the "scale" number NN of
/// index-tycho2-NN, index-42NN, index-52NN-xx).
struct IndexFile {
  std::string path;
  int scale = 0;
  double quadMinArcmin = 0.0;
  double quadMaxArcmin = 0.0;
};

/// Smallest and largest quad of astrometry.net index scale `scale` (0..19), arcmin. Throws st::InputError
/// outside 0..19.
std::pair<double, double> quadSizeArcmin(int scale);

/// The index files (index-*.fits) in `dirs` whose names give a scale number. Missing folders are skipped.
std::vector<IndexFile> findIndexFiles(const std::vector<std::string>& dirs);

/// The folders an astrometry.net configuration names (add_path lines; folders of `index` lines with a
/// path). Empty when the file cannot be read.
std::vector<std::string> configIndexDirs(const std::string& configPath);

/// The Debian index packages whose quads suit a field of largest side `fieldArcmin` (quads from 10% of the
/// side to the diagonal), e.g. "astrometry-data-tycho2-07-littleendian"; empty when the field is smaller
/// than the Tycho-2 packages cover (quads >= 22').
std::vector<std::string> indexPackagesFor(double fieldArcmin);

/// True when `index` has quads between 10% of the field's side and its diagonal.
bool indexSuitsField(const IndexFile& index, double fieldSideArcmin, double fieldDiagonalArcmin);

struct PlateSolution {
  std::shared_ptr<const Wcs> wcs;  ///< maps the 0-based pixels of the star list's frame
  FitsHeader header;               ///< solve-field's .wcs cards (1-based CRPIX)
  double scaleArcsecPerPx = 0.0;
  double centreRaDeg = 0.0;  ///< sky position of the frame centre ((width-1)/2, (height-1)/2)
  double centreDecDeg = 0.0;
  std::string index;   ///< the index file that solved it (from solve-field's log), when it says
  std::string method;  ///< "field index (...)" or "installed index files"
  std::size_t starsGiven = 0;
  double elapsedS = 0.0;
  std::string log;      ///< solve-field's stdout
  std::string workDir;  ///< kept only with PlateSolveParams::keepWorkDir
};

/// Solves the WCS of a width x height frame from `stars` (0-based px). Throws st::InputError with a message
/// the user can act on when solve-field is not installed (names the package astrometry.net), when no index
/// files are installed or none suits the field size that the scale hint implies (names the package to
/// install), for fewer than 4 stars, when solve-field fails (its stderr), and when no solution is found
/// within the time limit or at all; st::Cancelled when cancelled (solve-field is stopped first).
PlateSolution plateSolve(const std::vector<io::XyStar>& stars, int width, int height,
                         const PlateSolveParams& params, ProgressSink& progress, CancelToken& cancel);

}  // namespace st::astro

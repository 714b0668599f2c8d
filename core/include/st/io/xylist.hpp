#pragma once
// The files exchanged with astrometry.net's solve-field (astro/plate_solve.hpp): the star list it solves
// ("xylist", a FITS binary table) and the header-only FITS file in which it writes the solved WCS.
#include <string>
#include <vector>

#include "st/common/fits_header.hpp"

namespace st::io {

/// One star of a plate-solving star list. x, y are 0-based pixels (ARCHITECTURE.md); flux in any unit (only
/// its order matters: solve-field tries the brightest stars first).
struct XyStar {
  double x = 0.0;
  double y = 0.0;
  double flux = 0.0;
};

/// Column names of the table writeXylist writes (solve-field's --x-column/--y-column/--sort-column).
inline constexpr const char* kXylistXColumn = "X";
inline constexpr const char* kXylistYColumn = "Y";
inline constexpr const char* kXylistFluxColumn = "FLUX";

/// Writes `stars` as a FITS binary table (extension 1, EXTNAME "XYLIST"; columns X, Y, FLUX as 1D) at
/// `path` (overwritten), sorted by decreasing flux, with IMAGEW/IMAGEH = width/height in the table header.
/// X and Y are written 1-based (FITS's and astrometry.net's convention: the first pixel's centre is 1,1):
/// x + 1, y + 1. Stars with a non-finite coordinate or flux are left out. Throws st::InputError for
/// width/height <= 0, st::FitsError naming the file when CFITSIO fails.
void writeXylist(const std::string& path, const std::vector<XyStar>& stars, int width, int height);

/// Reads back a table written by writeXylist (0-based x, y, in file order). Throws st::FitsError.
std::vector<XyStar> readXylist(const std::string& path);

/// The header of HDU `hdu` (1-based, 1 = primary) of `path`, e.g. solve-field's header-only .wcs file.
/// Throws st::InputError for a missing file, st::FitsError naming the file otherwise.
FitsHeader readFitsHeader(const std::string& path, int hdu = 1);

/// Writes `header`'s keyword cards (no COMMENT/HISTORY, no structural keywords) into a header-only FITS file
/// at `path` (overwritten; NAXIS = 0), like solve-field's .wcs. Throws st::FitsError.
void writeHeaderFile(const std::string& path, const FitsHeader& header);

}  // namespace st::io

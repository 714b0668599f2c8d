#pragma once
// The astrometric reference catalogues the Minor Planet Center accepts: the ADES astCat value (the MPC's
// "ADES Field Values" list; a batch naming an unlisted catalogue is rejected), the one-character code of
// column 72 of the MPC1992 80-column record and the catalogue's name there (the MPC's "Catalogue Codes"
// page; the same pairs as IAU-ADES/ADES-Master Python/bin/packUtil.py catCodes), and whether the MPC lists
// it as deprecated. Column 72 is the MPC's to fill: a submission leaves it blank and names the catalogue on
// its NET header line (that page: "On new submissions, column 72 must be blank").
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "st/common/fits_header.hpp"

namespace st::report {

struct StarCatalogue {
  std::string_view astCat;   ///< ADES astCat, e.g. "Gaia3"
  char mpcCode = ' ';        ///< 80-column column 72 as the MPC fills it, e.g. 'W'
  bool deprecated = false;   ///< deprecated by the MPC (or not on its ADES list): a warning, not an error
  std::string_view mpcName;  ///< the "Catalogue Codes" page's name, for the NET line, e.g. "Gaia-DR3"
};

/// Every catalogue with an 80-column code, in the MPC's order of codes.
[[nodiscard]] const std::vector<StarCatalogue>& starCatalogues();
/// The catalogue with this ADES astCat (exact, case-sensitive as ADES is), or nullptr.
[[nodiscard]] const StarCatalogue* findStarCatalogue(std::string_view astCat);
/// Column 72 for an astCat: its code, or ' ' when the catalogue has none.
[[nodiscard]] char mpcCatalogueCode(std::string_view astCat);
/// The catalogue with this column-72 code, or nullptr.
[[nodiscard]] const StarCatalogue* findStarCatalogueByCode(char mpcCode);

/// The reference catalogue of a header's WCS solution, when the header names it. Recognised: astrometry.net's
/// "Index(N): .../index-NNNN.fits" COMMENT cards, whose series gives the catalogue (41xx Tycho-2 "Tyc2",
/// 42xx 2MASS "2MASS", 52xx Gaia DR2 "Gaia2"; its documentation, data.astrometry.net). nullopt otherwise: no
/// FITS keyword for it is standard, so the user names it (--ast-cat, the report dialog's catalogue).
[[nodiscard]] std::optional<std::string> astCatFromHeader(const FitsHeader& header);

}  // namespace st::report

#include "st/report/star_catalogues.hpp"

#include <cctype>
#include <regex>

namespace st::report {

const std::vector<StarCatalogue>& starCatalogues() {
  // USNOB2 and URAT2 have codes but are not on the MPC's ADES list: marked deprecated (a warning). The names
  // are the "Catalogue Codes" page's (codes 0 and 3-6 without one there: their astCat names the NET line).
  static const std::vector<StarCatalogue> kAll = {
      {"USNOA1", 'a', true, "USNO-A1.0"},
      {"USNOSA1", 'b', true, "USNO-SA1.0"},
      {"USNOA2", 'c', true, "USNO-A2.0"},
      {"USNOSA2", 'd', true, "USNO-SA2.0"},
      {"UCAC1", 'e', true, "UCAC-1"},
      {"Tyc1", 'f', true, "Tycho-1"},
      {"Tyc2", 'g', true, "Tycho-2"},
      {"GSC1.0", 'h', true, "GSC-1.0"},
      {"GSC1.1", 'i', true, "GSC-1.1"},
      {"GSC1.2", 'j', true, "GSC-1.2"},
      {"GSC2.2", 'k', true, "GSC-2.2"},
      {"ACT", 'l', true, "ACT"},
      {"GSCACT", 'm', true, "GSC-ACT"},
      {"SDSS8", 'n', true, "SDSS-DR8"},
      {"USNOB1", 'o', true, "USNO-B1.0"},
      {"PPM", 'p', true, "PPM"},
      {"UCAC4", 'q', false, "UCAC-4"},
      {"UCAC2", 'r', true, "UCAC-2"},
      {"USNOB2", 's', true, "USNO-B2.0"},
      {"PPMXL", 't', false, "PPMXL"},
      {"UCAC3", 'u', true, "UCAC-3"},
      {"NOMAD", 'v', false, "NOMAD"},
      {"CMC14", 'w', true, "CMC-14"},
      {"Hip2", 'x', true, "Hipparcos 2"},
      {"Hip1", 'y', true, "Hipparcos"},
      {"GSC", 'z', true, "GSC"},
      {"AC", 'A', true, "AC"},
      {"SAO1984", 'B', true, "SAO 1984"},
      {"SAO", 'C', true, "SAO"},
      {"AGK3", 'D', true, "AGK 3"},
      {"FK4", 'E', true, "FK4"},
      {"ACRS", 'F', true, "ACRS"},
      {"LickGas", 'G', true, "Lick Gaspra Catalogue"},
      {"Ida93", 'H', true, "Ida93 Catalogue"},
      {"Perth70", 'I', true, "Perth 70"},
      {"COSMOS", 'J', true, "COSMOS/UKST Southern Sky Catalogue"},
      {"Yale", 'K', true, "Yale"},
      {"2MASS", 'L', false, "2MASS"},
      {"GSC2.3", 'M', true, "GSC-2.3"},
      {"SDSS7", 'N', true, "SDSS-DR7"},
      {"SSTRC1", 'O', true, "SST-RC1"},
      {"MPOSC3", 'P', true, "MPOSC3"},
      {"CMC15", 'Q', true, "CMC-15"},
      {"SSTRC4", 'R', true, "SST-RC4"},
      {"URAT1", 'S', false, "URAT-1"},
      {"URAT2", 'T', true, "URAT-2"},
      {"Gaia1", 'U', false, "Gaia-DR1"},
      {"Gaia2", 'V', false, "Gaia-DR2"},
      {"Gaia3", 'W', false, "Gaia-DR3"},
      {"Gaia3E", 'X', false, "Gaia-EDR3"},
      {"UCAC5", 'Y', false, "UCAC-5"},
      {"ATLAS2", 'Z', false, "ATLAS-2"},
      {"IHW", '0', true},
      {"PS1_DR1", '1', false, "PS1-DR1"},
      {"PS1_DR2", '2', false, "PS1-DR2"},
      {"Gaia_Int", '3', false},
      {"GZ", '4', true},
      {"UBSC", '5', false},
      {"Gaia_2016", '6', false},
  };
  return kAll;
}

const StarCatalogue* findStarCatalogue(std::string_view astCat) {
  for (const auto& c : starCatalogues())
    if (c.astCat == astCat) return &c;
  return nullptr;
}

const StarCatalogue* findStarCatalogueByCode(char mpcCode) {
  for (const auto& c : starCatalogues())
    if (c.mpcCode == mpcCode) return &c;
  return nullptr;
}

char mpcCatalogueCode(std::string_view astCat) {
  const StarCatalogue* c = findStarCatalogue(astCat);
  return c ? c->mpcCode : ' ';
}

std::optional<std::string> astCatFromHeader(const FitsHeader& header) {
  // solve-field writes one "Index(i): <path>/index-NNNN[-xx].fits" comment per index it loaded; the series
  // (the thousands and hundreds) names the catalogue the index was built from.
  static const std::regex kIndex(R"(Index\(\d+\):.*index-(\d{2})\d{2}(-\d+)?\.fits)");
  std::optional<std::string> found;
  for (const auto& card : header.cards) {
    if (card.key != "COMMENT") continue;
    std::smatch m;
    if (!std::regex_search(card.comment, m, kIndex)) continue;
    const std::string series = m[1];
    std::string cat = series == "41" ? "Tyc2" : series == "42" ? "2MASS" : series == "52" ? "Gaia2" : "";
    if (cat.empty()) return std::nullopt;             // a series we cannot name: do not guess
    if (found && *found != cat) return std::nullopt;  // indexes of two catalogues: the one used is unknown
    found = cat;
  }
  return found;
}

}  // namespace st::report

#include "st/report/star_catalogues.hpp"

#include <cctype>
#include <regex>

namespace st::report {

const std::vector<StarCatalogue>& starCatalogues() {
  // USNOB2 and URAT2 have codes but are not on the MPC's ADES list: marked deprecated (a warning).
  static const std::vector<StarCatalogue> kAll = {
      {"USNOA1", 'a', true},  {"USNOSA1", 'b', true},  {"USNOA2", 'c', true},     {"USNOSA2", 'd', true},
      {"UCAC1", 'e', true},   {"Tyc1", 'f', true},     {"Tyc2", 'g', true},       {"GSC1.0", 'h', true},
      {"GSC1.1", 'i', true},  {"GSC1.2", 'j', true},   {"GSC2.2", 'k', true},     {"ACT", 'l', true},
      {"GSCACT", 'm', true},  {"SDSS8", 'n', true},    {"USNOB1", 'o', true},     {"PPM", 'p', true},
      {"UCAC4", 'q', false},  {"UCAC2", 'r', true},    {"USNOB2", 's', true},     {"PPMXL", 't', false},
      {"UCAC3", 'u', true},   {"NOMAD", 'v', false},   {"CMC14", 'w', true},      {"Hip2", 'x', true},
      {"Hip1", 'y', true},    {"GSC", 'z', true},      {"AC", 'A', true},         {"SAO1984", 'B', true},
      {"SAO", 'C', true},     {"AGK3", 'D', true},     {"FK4", 'E', true},        {"ACRS", 'F', true},
      {"LickGas", 'G', true}, {"Ida93", 'H', true},    {"Perth70", 'I', true},    {"COSMOS", 'J', true},
      {"Yale", 'K', true},    {"2MASS", 'L', false},   {"GSC2.3", 'M', true},     {"SDSS7", 'N', true},
      {"SSTRC1", 'O', true},  {"MPOSC3", 'P', true},   {"CMC15", 'Q', true},      {"SSTRC4", 'R', true},
      {"URAT1", 'S', false},  {"URAT2", 'T', true},    {"Gaia1", 'U', false},     {"Gaia2", 'V', false},
      {"Gaia3", 'W', false},  {"Gaia3E", 'X', false},  {"UCAC5", 'Y', false},     {"ATLAS2", 'Z', false},
      {"IHW", '0', true},     {"PS1_DR1", '1', false}, {"PS1_DR2", '2', false},   {"Gaia_Int", '3', false},
      {"GZ", '4', true},      {"UBSC", '5', false},    {"Gaia_2016", '6', false},
  };
  return kAll;
}

const StarCatalogue* findStarCatalogue(std::string_view astCat) {
  for (const auto& c : starCatalogues())
    if (c.astCat == astCat) return &c;
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

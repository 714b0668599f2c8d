#include "st/report/submission_settings.hpp"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cstring>

#include "st/common/error.hpp"
#include "st/report/star_catalogues.hpp"

namespace st::report {
namespace {

std::string trimmed(const std::string& s) {
  const auto b = s.find_first_not_of(" \t");
  const auto e = s.find_last_not_of(" \t");
  return b == std::string::npos ? std::string() : s.substr(b, e - b + 1);
}

bool allOf(const std::string& s, const char* extra) {
  return std::all_of(s.begin(), s.end(), [&](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || (c != '\0' && std::strchr(extra, c));
  });
}

// ADES StringType: not empty, not only blanks, no '|' (the PSV separator); one line.
bool plainText(const std::string& s, std::size_t maxChars) {
  return !trimmed(s).empty() && s.size() <= maxChars && s.find_first_of("|\n\r") == std::string::npos;
}

// The MPC's modes for electronic detectors ("ADES Field Values": CCD, CMOS, video, TDI CCD).
constexpr const char* kModes[] = {"CCD", "CMO", "VID", "TDI"};

void stationProblems(const SubmissionSettings& s, std::vector<SettingsProblem>& out) {
  if (s.stationCode.size() != 3 || !allOf(s.stationCode, ""))
    out.push_back({"station", "the MPC station code: 3 letters or digits, got '" + s.stationCode + "'"});
}

void adesProblems(const SubmissionSettings& s, std::vector<SettingsProblem>& out) {
  const std::string measurer = measurerOf(s);
  if (measurer.empty()) {
    out.push_back({"measurer", "a measurer (the measurer's name, or observers: the first is the measurer)"});
  } else if (!plainText(measurer, 100)) {
    out.push_back({"measurer", "a measurer name of 1-100 characters without '|', got '" + measurer + "'"});
  }
  for (const auto& name : observerNames(s))
    if (!plainText(name, 100))
      out.push_back({"observers", "observer names of 1-100 characters without '|': '" + name + "'"});
  if (!s.submitter.empty() && !plainText(s.submitter, 100))
    out.push_back({"submitter", "a submitter name of 1-100 characters without '|'"});
  if (!plainText(s.telescopeDesign, 25))
    out.push_back({"telescope_design",
                   "the telescope design (1-25 characters: reflector, refractor, Schmidt, ...), got '" +
                       s.telescopeDesign + "'"});
  char aperture[32];
  std::snprintf(aperture, sizeof aperture, "%g", s.apertureM);
  if (!(s.apertureM > 0.0 && s.apertureM < 1000.0))
    out.push_back(
        {"aperture_m", std::string("the telescope aperture in metres (> 0 and < 1000), got ") + aperture});
  if (std::find_if(std::begin(kModes), std::end(kModes), [&](const char* m) { return s.detector == m; }) ==
      std::end(kModes)) {
    out.push_back(
        {"detector", "the detector: CCD, CMO (CMOS), VID (video) or TDI, got '" + s.detector + "'"});
  }
  if (s.astCat.empty()) {
    out.push_back({"ast_cat",
                   "astCat, the reference catalogue of the astrometric solution (e.g. Gaia3, Gaia2, "
                   "UCAC4, PS1_DR2, ATLAS2)"});
  } else if (s.astCat.size() > 8 || !allOf(s.astCat, "._")) {
    out.push_back(
        {"ast_cat", "astCat as the MPC spells it: 1-8 of letters, digits, '.', '_' (e.g. Gaia3), got '" +
                        s.astCat + "'"});
  }
}

}  // namespace

std::string measurerOf(const SubmissionSettings& s) {
  if (!trimmed(s.measurer).empty()) return trimmed(s.measurer);
  const auto names = observerNames(s);
  return names.empty() ? std::string() : names.front();
}

std::vector<std::string> observerNames(const SubmissionSettings& s) {
  std::vector<std::string> out;
  std::size_t start = 0;
  while (start <= s.observers.size()) {
    const std::size_t comma = std::min(s.observers.find(',', start), s.observers.size());
    if (std::string name = trimmed(s.observers.substr(start, comma - start)); !name.empty())
      out.push_back(std::move(name));
    start = comma + 1;
  }
  return out;
}

char resolvedCatalogueCode(const SubmissionSettings& s) {
  return s.mpcCatalogCode != ' ' && s.mpcCatalogCode != '\0' ? s.mpcCatalogCode : mpcCatalogueCode(s.astCat);
}

std::string netCatalogueName(const SubmissionSettings& s) {
  const StarCatalogue* c = findStarCatalogueByCode(resolvedCatalogueCode(s));
  if (c && !c->mpcName.empty()) return std::string(c->mpcName);
  // A code given explicitly names its catalogue (by its astCat where the list gives it no other name).
  const bool given = s.mpcCatalogCode != ' ' && s.mpcCatalogCode != '\0';
  if (c && (given || s.astCat.empty())) return std::string(c->astCat);
  return s.astCat;
}

std::vector<SettingsProblem> submissionProblems(const SubmissionSettings& s, SubmissionFormat format) {
  std::vector<SettingsProblem> out;
  stationProblems(s, out);
  if (format == SubmissionFormat::Ades) {
    adesProblems(s, out);
  } else {
    const char code = s.mpcCatalogCode;
    if (code != ' ' && code != '\0' && !findStarCatalogueByCode(code)) {
      out.push_back(
          {"mpc_catalog_code",
           std::string("a catalogue code from the MPC's \"Catalogue Codes\" list, got '") + code + "'"});
    } else if (netCatalogueName(s).empty()) {
      out.push_back({"ast_cat",
                     "the reference catalogue of the astrometric solution for the NET line (astCat, "
                     "e.g. Gaia3)"});
    }
    const std::string& mail = s.contactEmail;
    if (!mail.empty() &&
        (std::count(mail.begin(), mail.end(), '@') != 1 || mail.front() == '@' || mail.back() == '@' ||
         mail.find_first_of(" \t|") != std::string::npos || mail.size() > 76))
      out.push_back(
          {"contact_email", "a contact e-mail address for the AC2 line (name@host), got '" + mail + "'"});
  }
  return out;
}

std::string problemsText(const std::vector<SettingsProblem>& problems, SubmissionFormat format) {
  std::string text = format == SubmissionFormat::Ades ? "ADES needs " : "MPC 80-column needs ";
  for (std::size_t i = 0; i < problems.size(); ++i)
    text += (i ? "; " : "") + problems[i].message;
  return text;
}

const char* toString(TrackletPositions p) noexcept {
  return p == TrackletPositions::Fit ? "fit" : "segments";
}

TrackletPositions trackletPositionsFromString(const std::string& text) {
  for (TrackletPositions p : {TrackletPositions::Segments, TrackletPositions::Fit})
    if (text == toString(p)) return p;
  throw InputError(
      "positions per object must be 'segments' (one per segment of the fit) or 'fit' (the whole "
      "fit's one position), got '" +
      text + "'");
}

nlohmann::json toJson(const SubmissionSettings& s) {
  return {{"station", s.stationCode},
          {"observers", s.observers},
          {"measurer", s.measurer},
          {"submitter", s.submitter},
          {"contact_email", s.contactEmail},
          {"telescope_design", s.telescopeDesign},
          {"aperture_m", s.apertureM},
          {"detector", s.detector},
          {"ast_cat", s.astCat},
          {"mpc_catalog_code", std::string(1, s.mpcCatalogCode)},
          {"safe_snr", s.safeSnr},
          {"positions", toString(s.positions)}};
}

SubmissionSettings submissionFromJson(const nlohmann::json& j) {
  SubmissionSettings s;
  if (!j.is_object()) return s;
  auto text = [&](const char* key, std::string& out) {
    if (auto it = j.find(key); it != j.end() && it->is_string()) out = it->get<std::string>();
  };
  auto number = [&](const char* key, double& out) {
    if (auto it = j.find(key); it != j.end() && it->is_number()) out = it->get<double>();
  };
  text("station", s.stationCode);
  text("observers", s.observers);
  text("measurer", s.measurer);
  text("submitter", s.submitter);
  text("contact_email", s.contactEmail);
  text("telescope_design", s.telescopeDesign);
  number("aperture_m", s.apertureM);
  text("detector", s.detector);
  text("ast_cat", s.astCat);
  std::string code;
  text("mpc_catalog_code", code);
  if (code.size() == 1) s.mpcCatalogCode = code[0];
  number("safe_snr", s.safeSnr);
  std::string positions;
  text("positions", positions);
  if (positions == toString(TrackletPositions::Fit)) s.positions = TrackletPositions::Fit;
  return s;
}

}  // namespace st::report

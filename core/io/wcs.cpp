// Wcs through wcslib. Headers are re-serialised card by card before wcspih, so numbers written as quoted
// strings (CRVAL1 = '124.6185920672', as SCAMP-solved Lowell headers have) are parsed as numbers, and
// SCAMP's TPV convention (CTYPE RA---TAN with PVi_m distortion terms) is recognised instead of having
// PV1_1..4 silently misread as TAN's projection parameters.
#include "st/io/wcs.hpp"

#include <wcslib/wcs.h>
#include <wcslib/wcsfix.h>
#include <wcslib/wcshdr.h>
#include <wcslib/wcsutil.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <mutex>

#include "fits_file.hpp"
#include "st/common/error.hpp"

namespace st {

struct Wcs::Impl {
  wcsprm* wcs = nullptr;
  int nwcs = 0;
  bool sip = false;
  bool tpv = false;
  mutable std::mutex mutex;  // wcslib may write into its struct (error records) on every call
  ~Impl() {
    if (wcs != nullptr) wcsvfree(&nwcs, &wcs);
  }
};

namespace {

bool startsWith(std::string_view s, std::string_view p) {
  return s.substr(0, p.size()) == p;
}

bool isNumber(const std::string& s) {
  std::string t = s;
  std::replace(t.begin(), t.end(), 'D', 'E');
  if (!t.empty() && t.front() == '+') t.erase(0, 1);
  double v = 0.0;
  const auto [ptr, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
  return !t.empty() && ec == std::errc() && ptr == t.data() + t.size();
}

std::string formatCard(const FitsCard& c, const std::string& key, bool asString) {
  char buf[160];
  if (asString) {
    std::string q;
    for (char ch : c.value)
      q += (ch == '\'') ? "''" : std::string(1, ch);
    std::snprintf(buf, sizeof buf, "%-8.8s= '%s'", key.c_str(), q.c_str());
  } else {
    std::snprintf(buf, sizeof buf, "%-8.8s= %20s", key.c_str(), c.value.c_str());
  }
  std::string card = buf;
  card.resize(80, ' ');
  return card;
}

// Header text for wcspih: WCS-relevant cards only, quoted numbers unquoted, and (for TPV) CTYPE rewritten.
std::string wcsHeaderText(const FitsHeader& header, bool tanAsTpv, bool dropPv) {
  std::string text;
  for (const auto& c : header.cards) {
    if (c.key.empty() || c.key == "COMMENT" || c.key == "HISTORY" || c.key.size() > 8) continue;
    if (!Wcs::isWcsKeyword(c.key) && !startsWith(c.key, "NAXIS")) continue;
    if (startsWith(c.key, "NAXIS")) continue;  // the WCS axis count comes from WCSAXES or the keywords
    if (dropPv && startsWith(c.key, "PV")) continue;
    FitsCard card = c;
    bool asString = c.isString && !isNumber(c.value);
    if (tanAsTpv && startsWith(c.key, "CTYPE") && card.value.size() >= 8 &&
        card.value.substr(4, 4) == "-TAN" && card.value.size() == 8) {
      card.value = card.value.substr(0, 4) + "-TPV";
    }
    if (!c.isString && !isNumber(c.value) && c.value != "T" && c.value != "F") continue;  // junk value
    text += formatCard(card, c.key, asString);
  }
  return text;
}

bool hasDistortionPv(const FitsHeader& header) {
  for (const auto& c : header.cards) {
    if (!startsWith(c.key, "PV1_") && !startsWith(c.key, "PV2_")) continue;
    return true;
  }
  return false;
}

bool ctypeIsPlainTan(const FitsHeader& header) {
  const auto t = header.getString("CTYPE1");
  return t && t->size() == 8 && t->substr(4) == "-TAN";
}

// The pixel -> intermediate matrix (CD, or CDELT * PC) as wcspih left it, before wcsset.
bool linearPartInvertible(const wcsprm& w) {
  const int n = w.naxis;
  if (n <= 0 || n > 9) return false;
  const bool cd = (w.altlin & 2) != 0 && (w.altlin & 1) == 0;
  std::vector<double> m(static_cast<std::size_t>(n * n));
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      m[i * n + j] = cd ? w.cd[i * n + j] : w.cdelt[i] * w.pc[i * n + j];
      if (!std::isfinite(m[i * n + j])) return false;
    }
  }
  // Gaussian elimination with partial pivoting: singular when a pivot vanishes.
  double scale = 0.0;
  for (double v : m)
    scale = std::max(scale, std::abs(v));
  if (scale == 0.0) return false;
  for (int c = 0; c < n; ++c) {
    int piv = c;
    for (int r = c + 1; r < n; ++r) {
      if (std::abs(m[r * n + c]) > std::abs(m[piv * n + c])) piv = r;
    }
    if (std::abs(m[piv * n + c]) <= 1e-14 * scale) return false;
    for (int k = 0; k < n; ++k)
      std::swap(m[c * n + k], m[piv * n + k]);
    for (int r = c + 1; r < n; ++r) {
      const double f = m[r * n + c] / m[c * n + c];
      for (int k = c; k < n; ++k)
        m[r * n + k] -= f * m[c * n + k];
    }
  }
  return true;
}

// Parses `text`, keeps the primary WCS when it has celestial axes. Returns an error text on failure.
std::string tryParse(std::string text, Wcs::Impl& impl) {
  const int nkeys = static_cast<int>(text.size() / 80);
  if (nkeys == 0) return "no WCS keywords";
  int nreject = 0;
  int status = wcspih(text.data(), nkeys, WCSHDR_all, 0, &nreject, &impl.nwcs, &impl.wcs);
  if (status != 0 || impl.nwcs == 0)
    return std::string("wcspih: ") + (status ? wcshdr_errmsg[status] : "no WCS");
  wcsprm* w = impl.wcs;
  // wcslib 7.12 leaks its matrices when linset() meets a singular matrix: refuse those here.
  if (!linearPartInvertible(*w)) return "the CD/PC matrix is singular";
  int stat[NWCSFIX] = {};
  wcsfix(1, nullptr, w, stat);  // translate non-standard units, CD/CDELT mixtures, RADECSYS, ...
  status = wcsset(w);
  if (status != 0) {
    std::string msg = w->err != nullptr ? w->err->msg : wcs_errmsg[status];
    return "wcsset: " + msg;
  }
  if (w->lng < 0 || w->lat < 0) return "no celestial axes";
  return {};
}

}  // namespace

bool Wcs::isWcsKeyword(std::string_view key) {
  static constexpr std::array<std::string_view, 24> kPrefixes = {
      "WCSAXES", "CRPIX", "CRVAL", "CTYPE",   "CUNIT",   "CDELT",   "CROTA",   "PC",
      "CD",      "PV",    "PS",    "A_",      "B_",      "AP_",     "BP_",     "DP",
      "DQ",      "CPDIS", "CQDIS", "LONPOLE", "LATPOLE", "RADESYS", "EQUINOX", "WCSNAME"};
  if (key == "RADECSYS" || key == "EPOCH") return true;
  if (startsWith(key, "CDELT") || startsWith(key, "CD")) {
    // CDi_j / CDELTi; not e.g. "CDATE".
    return key.size() > 2 && (std::isdigit(static_cast<unsigned char>(key[2])) || startsWith(key, "CDELT"));
  }
  if (startsWith(key, "PC")) return key.size() > 2 && std::isdigit(static_cast<unsigned char>(key[2]));
  if (startsWith(key, "PV") || startsWith(key, "PS") || startsWith(key, "DP") || startsWith(key, "DQ")) {
    return key.size() > 2 && std::isdigit(static_cast<unsigned char>(key[2]));
  }
  for (auto p : kPrefixes) {
    if (startsWith(key, p)) return true;
  }
  return false;
}

std::shared_ptr<const Wcs> Wcs::fromHeader(const FitsHeader& header, std::vector<std::string>* warnings) {
  auto warn = [&](const std::string& w) {
    if (warnings != nullptr) warnings->push_back(w);
  };
  if (!header.has("CTYPE1") && !header.has("CTYPE2")) return nullptr;
  const bool tpv = ctypeIsPlainTan(header) && hasDistortionPv(header);
  auto impl = std::make_unique<Impl>();
  std::string err = tryParse(wcsHeaderText(header, tpv, false), *impl);
  if (err.empty() && tpv) {
    impl->tpv = true;
    warn("WCS: CTYPE RA---TAN with PVi_m terms read as TPV distortion (SCAMP convention)");
  }
  if (!err.empty() && hasDistortionPv(header)) {
    impl = std::make_unique<Impl>();
    const std::string first = err;
    err = tryParse(wcsHeaderText(header, false, true), *impl);
    if (err.empty()) warn("WCS: PV distortion terms could not be used (" + first + "); dropped them");
  }
  if (!err.empty()) {
    warn("WCS: header has CTYPE keywords but no usable celestial WCS (" + err + "); ignored");
    return nullptr;
  }
  const std::string ct = impl->wcs->ctype[impl->wcs->lng];
  impl->sip = ct.find("-SIP") != std::string::npos;
  if (ct.find("-TPV") != std::string::npos) impl->tpv = true;
  return std::shared_ptr<const Wcs>(new Wcs(std::move(impl)));
}

Wcs::Wcs(std::unique_ptr<Impl> impl) : m_impl(std::move(impl)) {}
Wcs::~Wcs() = default;

Wcs::Sky Wcs::pixelToSky(double x, double y) const {
  std::lock_guard lock(m_impl->mutex);
  wcsprm* w = m_impl->wcs;
  std::vector<double> pix(w->naxis, 1.0), img(w->naxis), world(w->naxis);
  pix[0] = x + 1.0;
  if (w->naxis > 1) pix[1] = y + 1.0;
  double phi = 0.0;
  double theta = 0.0;
  int stat = 0;
  if (wcsp2s(w, 1, w->naxis, pix.data(), img.data(), &phi, &theta, world.data(), &stat) != 0) {
    throw InputError("WCS: pixel (" + std::to_string(x) + ", " + std::to_string(y) + ") has no sky position");
  }
  return Sky{world[w->lng], world[w->lat]};
}

std::pair<double, double> Wcs::skyToPixel(double raDeg, double decDeg) const {
  std::lock_guard lock(m_impl->mutex);
  wcsprm* w = m_impl->wcs;
  std::vector<double> pix(w->naxis), img(w->naxis), world(w->naxis);
  for (int i = 0; i < w->naxis; ++i)
    world[i] = w->crval[i];
  world[w->lng] = raDeg;
  world[w->lat] = decDeg;
  double phi = 0.0;
  double theta = 0.0;
  int stat = 0;
  if (wcss2p(w, 1, w->naxis, world.data(), &phi, &theta, img.data(), pix.data(), &stat) != 0) {
    throw InputError("WCS: sky position (" + std::to_string(raDeg) + ", " + std::to_string(decDeg) +
                     ") cannot be projected");
  }
  return {pix[0] - 1.0, (w->naxis > 1 ? pix[1] : 1.0) - 1.0};
}

double Wcs::plateScaleArcsecPerPx() const {
  const wcsprm* w = m_impl->wcs;
  const int n = w->naxis;
  // CDELT * PC, row = world axis, column = pixel axis (wcsset copies a CD matrix into pc with cdelt = 1).
  auto m = [&](int i, int j) { return w->cdelt[i] * w->pc[i * n + j]; };
  const double a = m(w->lng, 0), b = m(w->lng, 1), c = m(w->lat, 0), d = m(w->lat, 1);
  return std::sqrt(std::abs(a * d - b * c)) * 3600.0;
}

FitsHeader Wcs::toHeader() const {
  std::lock_guard lock(m_impl->mutex);
  int nkeys = 0;
  char* text = nullptr;
  if (wcshdo(WCSHDO_safe | WCSHDO_P17, m_impl->wcs, &nkeys, &text) != 0 || text == nullptr) {
    throw InputError("WCS: cannot write the WCS as header cards");
  }
  FitsHeader all = io::detail::parseHeaderText(text, nkeys);
  wcsdealloc(text);
  FitsHeader out;
  const wcsprm* w = m_impl->wcs;
  // wcshdo writes PCi_j + CDELTi; a header that came with a CD matrix gets its CDi_j back (astropy and DS9
  // users compare keywords).
  const bool cd = (w->altlin & 2) != 0 && (w->altlin & 1) == 0;
  auto isPcOrCdelt = [](const std::string& k) {
    return (startsWith(k, "PC") && k.size() > 2 && std::isdigit(static_cast<unsigned char>(k[2]))) ||
           startsWith(k, "CDELT");
  };
  for (auto& c : all.cards) {
    if (c.key.empty() || !isWcsKeyword(c.key) || (cd && isPcOrCdelt(c.key))) continue;
    out.cards.push_back(std::move(c));
  }
  if (cd) {
    for (int i = 0; i < w->naxis; ++i) {
      for (int j = 0; j < w->naxis; ++j) {
        const double v = w->cd[i * w->naxis + j];
        if (v != 0.0 || i == j) {
          out.setNumber("CD" + std::to_string(i + 1) + "_" + std::to_string(j + 1), v,
                        "linear transformation matrix");
        }
      }
    }
  }
  return out;
}

bool Wcs::hasSip() const {
  return m_impl->sip;
}
bool Wcs::hasTpv() const {
  return m_impl->tpv;
}

}  // namespace st

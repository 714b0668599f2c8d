#pragma once
// World coordinates of an image, through wcslib. Pixel coordinates here are 0-based (ARCHITECTURE.md); the
// conversion to FITS's 1-based pixels happens inside. Sky coordinates are ICRS degrees.
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "st/common/fits_header.hpp"

namespace st {

class Wcs {
 public:
  /// Parses the WCS of a header. Returns nullptr when the header has no celestial WCS. Numbers written as
  /// quoted strings are accepted; SIP distortion is read; TPV is read when wcslib can, else dropped with a
  /// warning appended to `warnings`. Never throws for a malformed WCS: it warns and returns nullptr.
  static std::shared_ptr<const Wcs> fromHeader(const FitsHeader& header, std::vector<std::string>* warnings);
  ~Wcs();
  Wcs(const Wcs&) = delete;
  Wcs& operator=(const Wcs&) = delete;

  struct Sky {
    double raDeg = 0.0;
    double decDeg = 0.0;
  };
  /// 0-based pixel -> sky. Throws st::InputError when the pixel has no valid sky position.
  [[nodiscard]] Sky pixelToSky(double x, double y) const;
  /// sky -> 0-based pixel. Throws st::InputError when the position cannot be projected.
  [[nodiscard]] std::pair<double, double> skyToPixel(double raDeg, double decDeg) const;
  /// Mean plate scale at the reference pixel, arcsec per pixel (sqrt of |det CD|).
  [[nodiscard]] double plateScaleArcsecPerPx() const;
  /// The WCS as header cards (for writing stacks), 1-based CRPIX as FITS wants.
  [[nodiscard]] FitsHeader toHeader() const;
  /// True when SIP distortion terms were read.
  [[nodiscard]] bool hasSip() const;
  /// True when TPV distortion (SCAMP's PVi_m on a TAN projection, or CTYPE -TPV) was read.
  [[nodiscard]] bool hasTpv() const;

  /// True for keywords that describe a WCS (CTYPEi, CRVALi, CRPIXi, CDi_j, PCi_j, CDELTi, PVi_m, SIP A_/B_/
  /// AP_/BP_ terms, RADESYS, EQUINOX, LONPOLE, ...). Writers use it to replace a header's WCS cards by
  /// toHeader()'s typed ones.
  static bool isWcsKeyword(std::string_view key);

  struct Impl;

 private:
  explicit Wcs(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> m_impl;
};

}  // namespace st

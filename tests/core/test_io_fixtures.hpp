#pragma once
// Small FITS fixtures for the io tests, written with CFITSIO directly (not with our writer, so reader
// tests do not depend on it).
#include <fitsio.h>

#include <cstdio>
#include <filesystem>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace st::test {

struct FixtureCard {
  std::string key;
  std::string value;  ///< written as given: "'text'" for strings, "1.5" for numbers
  std::string comment;
};

struct FixtureImage {
  int bitpix = -32;
  int width = 6;
  int height = 4;
  int planes = 0;           ///< 0 = 2-D image, else NAXIS3
  std::vector<double> raw;  ///< raw (stored) values, width*height*max(planes,1)
  std::optional<double> bzero, bscale;
  std::optional<long long> blank;
  std::vector<FixtureCard> cards;
  bool emptyPrimary = false;  ///< put the image in extension 1 after an empty primary
  std::string extname;
  int compress = 0;  ///< 0 or a CFITSIO compression type (RICE_1, GZIP_1)
};

inline void fixtureCheck(int status, const std::string& what) {
  if (status != 0) {
    char text[FLEN_STATUS];
    fits_get_errstatus(status, text);
    std::string stack;
    char msg[FLEN_ERRMSG];
    while (fits_read_errmsg(msg) != 0)
      stack += std::string(" | ") + msg;
    throw std::runtime_error("fixture: " + what + ": " + text + stack);
  }
}

/// Writes `img` to `path` (overwriting). A path ending in .gz is gzip-compressed by CFITSIO.
inline void writeFixture(const std::filesystem::path& path, const FixtureImage& img) {
  std::filesystem::remove(path);
  fitsfile* f = nullptr;
  int status = 0;
  fits_create_file(&f, path.string().c_str(), &status);
  fixtureCheck(status, "create " + path.string());
  if (img.emptyPrimary) {
    fits_create_img(f, 8, 0, nullptr, &status);
  }
  if (img.compress != 0) {
    fits_set_compression_type(f, img.compress, &status);
    if (img.bitpix < 0) fits_set_quantize_level(f, 0.0, &status);  // lossless for floats
  }
  long naxes[3] = {img.width, img.height, img.planes};
  // CFITSIO writes BZERO itself for unsigned types; compressed HDUs need it that way.
  const bool unsigned16 = img.compress != 0 && img.bitpix == 16 && img.bzero == 32768.0;
  fits_create_img(f, unsigned16 ? USHORT_IMG : img.bitpix, img.planes > 0 ? 3 : 2, naxes, &status);
  fixtureCheck(status, "create image");
  if (img.bzero && !unsigned16) fits_update_key_dbl(f, "BZERO", *img.bzero, -15, nullptr, &status);
  if (img.bscale) fits_update_key_dbl(f, "BSCALE", *img.bscale, -15, nullptr, &status);
  if (img.blank) {
    LONGLONG b = *img.blank;
    fits_update_key(f, TLONGLONG, "BLANK", &b, nullptr, &status);
  }
  if (!img.extname.empty()) fits_update_key_str(f, "EXTNAME", img.extname.c_str(), nullptr, &status);
  for (const auto& c : img.cards) {
    char card[FLEN_CARD];
    std::snprintf(card, sizeof card, "%-8s= %s / %s", c.key.c_str(), c.value.c_str(), c.comment.c_str());
    fits_update_card(f, c.key.c_str(), card, &status);
  }
  fixtureCheck(status, "keywords");
  std::vector<double> data = img.raw;
  if (img.compress == 0) {
    fits_set_bscale(f, 1.0, 0.0, &status);  // write the raw values as given
  } else {
    for (auto& v : data)
      v = v * img.bscale.value_or(1.0) + img.bzero.value_or(0.0);  // CFITSIO scales back
  }
  const auto n = static_cast<LONGLONG>(data.size());
  if (img.compress == 0) {
    fits_write_img(f, TDOUBLE, 1, n, data.data(), &status);
  } else if (unsigned16) {  // compressed images need the native type
    std::vector<unsigned short> v(data.begin(), data.end());
    fits_write_img(f, TUSHORT, 1, n, v.data(), &status);
  } else if (img.bitpix == 16) {
    std::vector<short> v(data.begin(), data.end());
    fits_write_img(f, TSHORT, 1, n, v.data(), &status);
  } else if (img.bitpix == 32) {
    std::vector<int> v(data.begin(), data.end());
    fits_write_img(f, TINT, 1, n, v.data(), &status);
  } else {
    std::vector<float> v(data.begin(), data.end());
    fits_write_img(f, TFLOAT, 1, n, v.data(), &status);
  }
  fixtureCheck(status, "write pixels");
  fits_close_file(f, &status);
  fixtureCheck(status, "close");
}

/// A float frame with DATE-OBS (start) and EXPTIME; pixel value = base + index.
inline FixtureImage timedFrame(const std::string& dateObs, double exptime, double base, int w = 6,
                               int h = 4) {
  FixtureImage img;
  img.width = w;
  img.height = h;
  for (int i = 0; i < w * h; ++i)
    img.raw.push_back(base + i);
  img.cards.push_back({"DATE-OBS", "'" + dateObs + "'", "exposure start"});
  img.cards.push_back({"EXPTIME", std::to_string(exptime), "s"});
  return img;
}

}  // namespace st::test

#include "st/io/fits_copy.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <limits>
#include <map>

#include "fits_file.hpp"
#include "st/common/error.hpp"

namespace st::io {
namespace {

/// Physical range of an image of CFITSIO's equivalent type `equivType`; infinite for floating point.
std::pair<double, double> rangeOf(int equivType) {
  constexpr double inf = std::numeric_limits<double>::infinity();
  switch (equivType) {
    case BYTE_IMG: return {0.0, 255.0};
    case SBYTE_IMG: return {-128.0, 127.0};
    case SHORT_IMG: return {-32768.0, 32767.0};
    case USHORT_IMG: return {0.0, 65535.0};
    case LONG_IMG: return {-2147483648.0, 2147483647.0};
    case ULONG_IMG: return {0.0, 4294967295.0};
    case LONGLONG_IMG: return {-9.2e18, 9.2e18};
    case ULONGLONG_IMG: return {0.0, 1.8e19};
    default: return {-inf, inf};
  }
}

void writeCard(const detail::FitsFile& f, const FitsCard& c) {
  int status = 0;
  const char* comment = c.comment.empty() ? nullptr : c.comment.c_str();
  double number = 0.0;
  const auto [end, ec] = std::from_chars(c.value.data(), c.value.data() + c.value.size(), number);
  if (c.isString || ec != std::errc() || end != c.value.data() + c.value.size()) {
    std::string v = c.value;
    fits_update_key_longstr(f.get(), c.key.c_str(), v.data(), comment, &status);
  } else if (c.value.find_first_of(".eE") == std::string::npos) {
    LONGLONG v = std::stoll(c.value);
    fits_update_key(f.get(), TLONGLONG, c.key.c_str(), &v, comment, &status);
  } else {
    fits_update_key_dbl(f.get(), c.key.c_str(), number, -15, comment, &status);
  }
  f.check(status, "writing keyword " + c.key);
}

bool hasKey(const detail::FitsFile& f, const char* key) {
  char card[FLEN_CARD] = {};
  int status = 0;
  fits_read_card(f.get(), key, card, &status);
  if (status == KEY_NO_EXIST) fits_clear_errmsg();
  return status == 0;
}

/// Adds `add` to plane `plane` of the current image HDU of `out`; returns the pixels clipped.
std::size_t addToPlane(const detail::FitsFile& out, int plane, const Image& add) {
  int status = 0, naxis = 0, equiv = 0;
  long dims[3] = {1, 1, 1};
  fits_get_img_equivtype(out.get(), &equiv, &status);
  fits_get_img_dim(out.get(), &naxis, &status);
  out.check(status, "reading the image type");
  if (naxis < 2 || naxis > 3) out.check(BAD_NAXIS, "the image has " + std::to_string(naxis) + " axes");
  fits_get_img_size(out.get(), naxis, dims, &status);
  out.check(status, "reading the image size");
  if (dims[0] != add.width || dims[1] != add.height || plane < 0 || plane >= dims[2]) {
    throw InputError(out.path() + " HDU " + std::to_string(out.currentHdu()) + ": image is " +
                     std::to_string(dims[0]) + " x " + std::to_string(dims[1]) + " x " + std::to_string(dims[2]) +
                     ", cannot add a " + std::to_string(add.width) + " x " + std::to_string(add.height) +
                     " image to plane " + std::to_string(plane));
  }
  const auto n = static_cast<LONGLONG>(add.size());
  long first[3] = {1, 1, plane + 1};
  std::vector<double> pixels(add.size());
  std::vector<char> nulls(add.size(), 0);
  int anyNull = 0;
  fits_read_pixnull(out.get(), TDOUBLE, first, n, pixels.data(), nulls.data(), &anyNull, &status);
  out.check(status, "reading plane " + std::to_string(plane));
  const auto [lo, hi] = rangeOf(equiv);
  const bool integer = std::isfinite(lo);
  constexpr double kNull = -9.1e307;  // outside every integer range; written back as BLANK or NaN
  std::size_t clipped = 0;
  for (std::size_t i = 0; i < pixels.size(); ++i) {
    if (nulls[i] != 0) {
      pixels[i] = kNull;
      continue;
    }
    double v = pixels[i] + add.pixels[i];
    if (integer) {
      v = std::round(v);
      if (v < lo || v > hi) {
        v = std::clamp(v, lo, hi);
        ++clipped;
      }
    }
    pixels[i] = v;
  }
  double nullValue = kNull;
  fits_write_pixnull(out.get(), TDOUBLE, first, n, pixels.data(), anyNull ? &nullValue : nullptr, &status);
  out.check(status, "writing plane " + std::to_string(plane));
  return clipped;
}

}  // namespace

CopyReport copyWithAddedPixels(const std::string& src, const std::string& dst,
                               const std::vector<PlaneAddition>& additions, const FitsHeader& cards,
                               const std::vector<std::string>& history) {
  std::map<int, std::vector<const PlaneAddition*>> byHdu;
  for (const auto& a : additions) {
    if (a.add == nullptr) throw InputError(src + ": no image given for HDU " + std::to_string(a.hdu));
    byHdu[a.hdu].push_back(&a);
  }
  const detail::FitsFile in = detail::FitsFile::openRead(src);
  detail::FitsFile out = detail::FitsFile::create(dst);
  int status = 0, hdus = 0;
  fits_get_num_hdus(in.get(), &hdus, &status);
  in.check(status, "counting HDUs");
  if (!byHdu.empty() && byHdu.rbegin()->first > hdus)
    throw InputError(src + ": has " + std::to_string(hdus) + " HDUs, no HDU " +
                     std::to_string(byHdu.rbegin()->first));
  CopyReport report;
  for (int h = 1; h <= hdus; ++h) {
    int type = 0;
    fits_movabs_hdu(in.get(), h, &type, &status);
    in.check(status, "moving to the HDU");
    const bool compressed = fits_is_compressed_image(in.get(), &status) != 0;
    if (compressed) {
      // Decompressed in memory first: fits_img_decompress writes into an empty primary of its output when
      // it can, which would move the image from HDU h to HDU 1; copied from memory it stays at HDU h.
      fitsfile* mem = nullptr;
      fits_create_file(&mem, "mem://", &status);
      in.check(status, "creating a memory file to decompress into");
      fits_img_decompress(in.get(), mem, &status);
      if (status == 0) fits_copy_hdu(mem, out.get(), 0, &status);
      int closeStatus = 0;
      fits_close_file(mem, &closeStatus);
      in.check(status, "decompressing the image");
    } else {
      fits_copy_hdu(in.get(), out.get(), 0, &status);
      in.check(status, "copying the HDU");
    }
    // Re-read the new HDU's structure so that its scaling (BZERO/BSCALE) and size are the ones in force.
    fits_movabs_hdu(out.get(), h, nullptr, &status);
    out.check(status, "moving to the copied HDU");
    const auto edits = byHdu.find(h);
    const bool edited = edits != byHdu.end();
    if (edited) {
      if (!compressed && type != IMAGE_HDU) throw InputError(src + " HDU " + std::to_string(h) + " is not an image");
      for (const PlaneAddition* a : edits->second)
        report.clippedPixels += addToPlane(out, a->plane, *a->add);
      for (const auto& c : cards.cards)
        writeCard(out, c);
      for (const auto& line : history) {
        fits_write_history(out.get(), line.c_str(), &status);
        out.check(status, "writing HISTORY");
      }
    }
    if ((edited || compressed) && hasKey(out, "CHECKSUM")) {
      fits_write_chksum(out.get(), &status);
      out.check(status, "updating CHECKSUM");
    }
    ++report.hdus;
  }
  out.close();
  return report;
}

}  // namespace st::io

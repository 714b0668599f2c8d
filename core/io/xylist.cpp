#include "st/io/xylist.hpp"

#include <algorithm>
#include <cmath>

#include "fits_file.hpp"
#include "st/common/error.hpp"
#include "st/io/fits_writer.hpp"

namespace st::io {

void writeXylist(const std::string& path, const std::vector<XyStar>& stars, int width, int height) {
  if (width <= 0 || height <= 0)
    throw InputError("xylist '" + path + "': image size must be positive, got " + std::to_string(width) +
                     " x " + std::to_string(height));
  std::vector<XyStar> kept;
  kept.reserve(stars.size());
  for (const XyStar& s : stars)
    if (std::isfinite(s.x) && std::isfinite(s.y) && std::isfinite(s.flux)) kept.push_back(s);
  std::stable_sort(kept.begin(), kept.end(),
                   [](const XyStar& a, const XyStar& b) { return a.flux > b.flux; });

  detail::FitsFile f = detail::FitsFile::create(path);
  int status = 0;
  // An empty primary HDU, then the table (solve-field reads extension 1 by default).
  fits_create_img(f.get(), BYTE_IMG, 0, nullptr, &status);
  f.check(status, "creating the primary HDU");
  char* ttype[] = {const_cast<char*>(kXylistXColumn), const_cast<char*>(kXylistYColumn),
                   const_cast<char*>(kXylistFluxColumn)};
  char* tform[] = {const_cast<char*>("1D"), const_cast<char*>("1D"), const_cast<char*>("1D")};
  char* tunit[] = {const_cast<char*>("pix"), const_cast<char*>("pix"), const_cast<char*>("")};
  fits_create_tbl(f.get(), BINARY_TBL, static_cast<LONGLONG>(kept.size()), 3, ttype, tform, tunit, "XYLIST",
                  &status);
  f.check(status, "creating the XYLIST table");
  int w = width, h = height;
  fits_update_key(f.get(), TINT, "IMAGEW", &w, "image width, px", &status);
  fits_update_key(f.get(), TINT, "IMAGEH", &h, "image height, px", &status);
  fits_write_comment(f.get(), "X, Y are 1-based pixel centres (FITS convention; first pixel 1,1)", &status);
  if (!kept.empty()) {
    std::vector<double> x, y, flux;
    for (const XyStar& s : kept) {
      x.push_back(s.x + 1.0);  // 0-based (ARCHITECTURE.md) -> FITS 1-based, here at the writer
      y.push_back(s.y + 1.0);
      flux.push_back(s.flux);
    }
    const auto n = static_cast<LONGLONG>(kept.size());
    fits_write_col(f.get(), TDOUBLE, 1, 1, 1, n, x.data(), &status);
    fits_write_col(f.get(), TDOUBLE, 2, 1, 1, n, y.data(), &status);
    fits_write_col(f.get(), TDOUBLE, 3, 1, 1, n, flux.data(), &status);
  }
  f.check(status, "writing the XYLIST table");
  f.close();
}

std::vector<XyStar> readXylist(const std::string& path) {
  detail::FitsFile f = detail::FitsFile::openRead(path);
  int status = 0;
  fits_movabs_hdu(f.get(), 2, nullptr, &status);
  f.check(status, "moving to the XYLIST table");
  long rows = 0;
  fits_get_num_rows(f.get(), &rows, &status);
  f.check(status, "reading the number of rows");
  std::vector<double> cols[3];
  const char* names[3] = {kXylistXColumn, kXylistYColumn, kXylistFluxColumn};
  for (int c = 0; c < 3; ++c) {
    int colnum = 0;
    fits_get_colnum(f.get(), CASEINSEN, const_cast<char*>(names[c]), &colnum, &status);
    f.check(status, std::string("finding column ") + names[c]);
    cols[c].resize(static_cast<std::size_t>(rows));
    if (rows > 0)
      fits_read_col(f.get(), TDOUBLE, colnum, 1, 1, rows, nullptr, cols[c].data(), nullptr, &status);
    f.check(status, std::string("reading column ") + names[c]);
  }
  std::vector<XyStar> out(static_cast<std::size_t>(rows));
  for (std::size_t i = 0; i < out.size(); ++i)
    out[i] = XyStar{cols[0][i] - 1.0, cols[1][i] - 1.0, cols[2][i]};
  return out;
}

FitsHeader readFitsHeader(const std::string& path, int hdu) {
  detail::FitsFile f = detail::FitsFile::openRead(path);
  int status = 0;
  fits_movabs_hdu(f.get(), hdu, nullptr, &status);
  f.check(status, "moving to HDU " + std::to_string(hdu));
  return detail::readHeader(f);
}

void writeHeaderFile(const std::string& path, const FitsHeader& header) {
  detail::FitsFile f = detail::FitsFile::create(path);
  int status = 0;
  fits_create_img(f.get(), BYTE_IMG, 0, nullptr, &status);
  f.check(status, "creating the header");
  for (const FitsCard& c : header.cards) {
    if (c.key.empty() || c.key == "COMMENT" || c.key == "HISTORY" || c.key == "END" ||
        isStructuralKeyword(c.key))
      continue;
    std::string card = c.key;
    card.resize(8, ' ');
    std::string value = c.value;
    if (c.isString) {
      for (std::size_t i = value.find('\''); i != std::string::npos; i = value.find('\'', i + 2))
        value.insert(i, 1, '\'');  // FITS doubles a quote inside a string
      value = "'" + value + "'";
    }
    card += "= " + value;
    if (!c.comment.empty()) card += " / " + c.comment;
    if (card.size() > 80) card.resize(80);
    fits_write_record(f.get(), card.c_str(), &status);
  }
  f.check(status, "writing the header");
  f.close();
}

}  // namespace st::io

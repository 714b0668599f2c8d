#include "st/io/fits_writer.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>

#include "fits_file.hpp"
#include "st/common/error.hpp"
#include "st/config.hpp"
#include "st/io/wcs.hpp"

namespace st::io {
namespace {

using detail::FitsFile;

bool startsWith(std::string_view s, std::string_view p) {
  return s.substr(0, p.size()) == p;
}

enum class ValueKind { Integer, Real, Logical, Other };

ValueKind classify(const std::string& text) {
  if (text == "T" || text == "F") return ValueKind::Logical;
  std::string t = text;
  if (!t.empty() && t.front() == '+') t.erase(0, 1);
  long long i = 0;
  if (auto [p, ec] = std::from_chars(t.data(), t.data() + t.size(), i);
      !t.empty() && ec == std::errc() && p == t.data() + t.size()) {
    return ValueKind::Integer;
  }
  std::replace(t.begin(), t.end(), 'D', 'E');
  double d = 0.0;
  if (auto [p, ec] = std::from_chars(t.data(), t.data() + t.size(), d);
      !t.empty() && ec == std::errc() && p == t.data() + t.size()) {
    return std::isfinite(d) ? ValueKind::Real : ValueKind::Other;
  }
  return ValueKind::Other;
}

void writeCard(const FitsFile& f, const FitsCard& c) {
  if (c.key.empty()) return;
  int status = 0;
  if (c.key == "COMMENT" || c.key == "HISTORY") {
    std::string text = c.comment.empty() ? c.value : c.comment;
    if (c.key == "COMMENT") {
      fits_write_comment(f.get(), text.c_str(), &status);
    } else {
      fits_write_history(f.get(), text.c_str(), &status);
    }
    f.check(status, "writing " + c.key);
    return;
  }
  std::string key = c.key;
  const char* comment = c.comment.empty() ? nullptr : c.comment.c_str();
  // WCS values written as quoted numbers by some pipelines become numbers (astropy and wcslib want numbers).
  const ValueKind kind = classify(c.value);
  const bool asString =
      c.isString ? !(Wcs::isWcsKeyword(key) && (kind == ValueKind::Integer || kind == ValueKind::Real))
                 : kind == ValueKind::Other;
  if (asString) {
    std::string v = c.value;
    fits_update_key_longstr(f.get(), key.c_str(), v.data(), comment, &status);
  } else if (kind == ValueKind::Logical) {
    int b = c.value == "T" ? 1 : 0;
    fits_update_key(f.get(), TLOGICAL, key.c_str(), &b, comment, &status);
  } else if (kind == ValueKind::Integer) {
    std::string t = c.value;
    if (t.front() == '+') t.erase(0, 1);
    LONGLONG v = std::stoll(t);
    fits_update_key(f.get(), TLONGLONG, key.c_str(), &v, comment, &status);
  } else {
    std::string t = c.value;
    std::replace(t.begin(), t.end(), 'D', 'E');
    double v = std::stod(t);
    fits_update_key_dbl(f.get(), key.c_str(), v, -17, comment, &status);
  }
  f.check(status, "writing keyword " + key + " = '" + c.value + "'");
}

void writeCards(const FitsFile& f, const FitsHeader& h, const Wcs* wcs) {
  for (const auto& c : h.cards) {
    if (isStructuralKeyword(c.key)) continue;
    if (wcs != nullptr && Wcs::isWcsKeyword(c.key)) continue;
    writeCard(f, c);
  }
  if (wcs != nullptr) {
    for (const auto& c : wcs->toHeader().cards)
      writeCard(f, c);
  }
}

std::string utcNowIso() {
  const std::time_t now = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  std::tm tm{};
  gmtime_r(&now, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%S", &tm);
  return buf;
}

void writeFramesTable(const FitsFile& f, const FrameCube& cube) {
  const long n = static_cast<long>(cube.frameCount());
  std::size_t width = 1;
  for (const auto& i : cube.info())
    width = std::max(width, i.file.size());
  const std::string fileForm = std::to_string(width) + "A";
  // REGX_PX/REGY_PX: the frames' registration offsets, only when some frame has one.
  char* ttype[] = {const_cast<char*>("MJD_MID"), const_cast<char*>("EXPTIME"), const_cast<char*>("FILE"),
                   const_cast<char*>("HDU"),     const_cast<char*>("PLANE"),   const_cast<char*>("REGX_PX"),
                   const_cast<char*>("REGY_PX")};
  char* tform[] = {const_cast<char*>("1D"), const_cast<char*>("1D"), const_cast<char*>(fileForm.c_str()),
                   const_cast<char*>("1J"), const_cast<char*>("1J"), const_cast<char*>("1D"),
                   const_cast<char*>("1D")};
  char* tunit[] = {const_cast<char*>("d"), const_cast<char*>("s"),  const_cast<char*>(""), const_cast<char*>(""),
                   const_cast<char*>(""),  const_cast<char*>("px"), const_cast<char*>("px")};
  const bool registered = cube.hasFrameOffsets();
  int status = 0;
  fits_create_tbl(f.get(), BINARY_TBL, n, registered ? 7 : 5, ttype, tform, tunit, "FRAMES", &status);
  f.check(status, "creating the FRAMES table");
  std::vector<double> mjd, exp;
  std::vector<int> hdu, plane;
  std::vector<std::string> files;
  std::vector<char*> filePtrs;
  for (const auto& i : cube.info()) {
    mjd.push_back(i.mjdMid);
    exp.push_back(i.exposureS);
    hdu.push_back(i.hdu);
    plane.push_back(i.plane);
    files.push_back(i.file.empty() ? std::string(" ") : i.file);
  }
  for (auto& s : files)
    filePtrs.push_back(s.data());
  fits_write_col(f.get(), TDOUBLE, 1, 1, 1, n, mjd.data(), &status);
  fits_write_col(f.get(), TDOUBLE, 2, 1, 1, n, exp.data(), &status);
  fits_write_col(f.get(), TSTRING, 3, 1, 1, n, filePtrs.data(), &status);
  fits_write_col(f.get(), TINT, 4, 1, 1, n, hdu.data(), &status);
  fits_write_col(f.get(), TINT, 5, 1, 1, n, plane.data(), &status);
  if (registered) {
    std::vector<double> rx, ry;
    for (const auto& i : cube.info()) {
      rx.push_back(i.offsetXPx);
      ry.push_back(i.offsetYPx);
    }
    fits_write_col(f.get(), TDOUBLE, 6, 1, 1, n, rx.data(), &status);
    fits_write_col(f.get(), TDOUBLE, 7, 1, 1, n, ry.data(), &status);
  }
  f.check(status, "writing the FRAMES table");
  fits_write_comment(f.get(),
                     "One row per plane of the primary cube: mid-exposure MJD (UTC), exposure (s), origin.",
                     &status);
}

}  // namespace

bool isStructuralKeyword(std::string_view key) {
  static constexpr std::string_view kExact[] = {
      "SIMPLE",   "BITPIX",  "EXTEND", "BZERO",   "BSCALE", "BLANK",   "PCOUNT", "GCOUNT", "XTENSION",
      "CHECKSUM", "DATASUM", "END",    "TFIELDS", "THEAP",  "EXTNAME", "EXTVER", "INHERIT"};
  for (auto k : kExact) {
    if (key == k) return true;
  }
  if (startsWith(key, "NAXIS")) return true;
  if (key.size() > 1 && key[0] == 'Z' &&
      (startsWith(key, "ZIMAGE") || startsWith(key, "ZBITPIX") || startsWith(key, "ZNAXIS") ||
       startsWith(key, "ZTILE") || startsWith(key, "ZCMPTYPE") || startsWith(key, "ZNAME") ||
       startsWith(key, "ZVAL") || startsWith(key, "ZQUANTIZ") || startsWith(key, "ZDITHER") ||
       startsWith(key, "ZSIMPLE") || startsWith(key, "ZTENSION") || startsWith(key, "ZEXTEND") ||
       startsWith(key, "ZPCOUNT") || startsWith(key, "ZGCOUNT") || startsWith(key, "ZHECKSUM") ||
       startsWith(key, "ZDATASUM") || startsWith(key, "ZBLANK") || startsWith(key, "ZSCALE") ||
       startsWith(key, "ZZERO"))) {
    return true;
  }
  for (auto p : {"TTYPE", "TFORM", "TUNIT", "TDIM", "TNULL", "TSCAL", "TZERO", "TDISP"}) {
    if (startsWith(key, p) && key.size() > std::string_view(p).size() &&
        std::isdigit(static_cast<unsigned char>(key[std::string_view(p).size()]))) {
      return true;
    }
  }
  return false;
}

void writeCube(const std::string& path, const FrameCube& cube, const FitsHeader& extra) {
  if (cube.empty()) throw InputError(path + ": cannot write an empty cube (zero frames)");
  FitsFile f = FitsFile::create(path);
  int status = 0;
  long naxes[3] = {cube.width(), cube.height(), static_cast<long>(cube.frameCount())};
  fits_create_img(f.get(), FLOAT_IMG, 3, naxes, &status);
  f.check(status, "creating the image");
  writeCards(f, cube.header, cube.wcs.get());
  writeCards(f, extra, nullptr);
  const std::size_t n = cube.framePixels();
  std::vector<float> buffer;
  for (std::size_t k = 0; k < cube.frameCount(); ++k) {
    const float* src = cube.frame(k);
    if (!cube.mask().empty()) {
      buffer.assign(src, src + n);
      const std::uint8_t* m = cube.mask().data() + k * n;
      for (std::size_t i = 0; i < n; ++i) {
        if (m[i] != 0) buffer[i] = std::nanf("");
      }
      src = buffer.data();
    }
    fits_write_img(f.get(), TFLOAT, static_cast<LONGLONG>(k * n + 1), static_cast<LONGLONG>(n),
                   const_cast<float*>(src), &status);
    f.check(status, "writing plane " + std::to_string(k + 1));
  }
  writeFramesTable(f, cube);
  f.close();
}

struct CubeRegionWriter::Impl {
  FitsFile file;
  int width = 0, height = 0;
  std::size_t frames = 0;
  std::vector<float> row;
};

CubeRegionWriter::CubeRegionWriter(const std::string& path, int width, int height, std::size_t frames,
                                   const FitsHeader& header, const Wcs* wcs, const FitsHeader& extra) {
  if (width <= 0 || height <= 0 || frames == 0)
    throw InputError(path + ": cannot write an empty cube (" + std::to_string(width) + " x " +
                     std::to_string(height) + " x " + std::to_string(frames) + ")");
  m_impl = std::make_unique<Impl>(Impl{FitsFile::create(path), width, height, frames, {}});
  int status = 0;
  long naxes[3] = {width, height, static_cast<long>(frames)};
  fits_create_img(m_impl->file.get(), FLOAT_IMG, 3, naxes, &status);
  m_impl->file.check(status, "creating the image");
  writeCards(m_impl->file, header, wcs);
  writeCards(m_impl->file, extra, nullptr);
}

CubeRegionWriter::~CubeRegionWriter() = default;

void CubeRegionWriter::write(const FrameCube& region, int srcX0, int srcY0, int cols, int rows, int x0, int y0) {
  Impl& m = *m_impl;
  if (region.frameCount() != m.frames || cols <= 0 || rows <= 0 || srcX0 < 0 || srcY0 < 0 ||
      srcX0 + cols > region.width() || srcY0 + rows > region.height() || x0 < 0 || y0 < 0 ||
      x0 + cols > m.width || y0 + rows > m.height)
    throw InputError(m.file.path() + ": a region of " + std::to_string(cols) + " x " + std::to_string(rows) +
                     " px at (" + std::to_string(x0) + ", " + std::to_string(y0) +
                     ") does not fit the cube or its source");
  const std::size_t rw = static_cast<std::size_t>(region.width());
  const std::size_t plane = region.framePixels();
  m.row.resize(static_cast<std::size_t>(cols) * static_cast<std::size_t>(rows));
  int status = 0;
  for (std::size_t k = 0; k < m.frames; ++k) {
    const float* src = region.frame(k);
    const std::uint8_t* mask = region.mask().empty() ? nullptr : region.mask().data() + k * plane;
    for (int r = 0; r < rows; ++r) {
      const std::size_t from = static_cast<std::size_t>(srcY0 + r) * rw + static_cast<std::size_t>(srcX0);
      float* to = m.row.data() + static_cast<std::size_t>(r) * static_cast<std::size_t>(cols);
      for (int c = 0; c < cols; ++c)
        to[c] = (mask != nullptr && mask[from + static_cast<std::size_t>(c)] != 0) ? std::nanf("")
                                                                                  : src[from + static_cast<std::size_t>(c)];
    }
    // FITS's 1-based, inclusive corners; one frame per call.
    long first[3] = {x0 + 1, y0 + 1, static_cast<long>(k) + 1};
    long last[3] = {x0 + cols, y0 + rows, static_cast<long>(k) + 1};
    fits_write_subset(m.file.get(), TFLOAT, first, last, m.row.data(), &status);
    m.file.check(status, "writing rows " + std::to_string(y0 + 1) + "-" + std::to_string(y0 + rows) +
                             " of plane " + std::to_string(k + 1));
  }
}

void CubeRegionWriter::updateCards(const FitsHeader& cards) {
  writeCards(m_impl->file, cards, nullptr);
}

void CubeRegionWriter::finish(const FrameCube& frames) {
  if (frames.frameCount() != m_impl->frames)
    throw InputError(m_impl->file.path() + ": the FRAMES table needs " + std::to_string(m_impl->frames) +
                     " frames, got " + std::to_string(frames.frameCount()));
  writeFramesTable(m_impl->file, frames);
  m_impl->file.close();
}

void writeImage(const std::string& path, const Image& image, const FitsHeader& header) {
  if (image.empty()) throw InputError(path + ": cannot write an empty image");
  FitsFile f = FitsFile::create(path);
  int status = 0;
  long naxes[2] = {image.width, image.height};
  fits_create_img(f.get(), FLOAT_IMG, 2, naxes, &status);
  f.check(status, "creating the image");
  writeCards(f, header, nullptr);
  fits_write_img(f.get(), TFLOAT, 1, static_cast<LONGLONG>(image.size()), const_cast<float*>(image.data()),
                 &status);
  f.check(status, "writing the pixels");
  f.close();
}

FitsHeader provenanceCards(const std::string& step, const FitsHeader& parameters) {
  FitsHeader h;
  h.setString("SOFTWARE", std::string("synthtrack ") + ST_VERSION, "software that wrote this file");
  h.setString("STEP", step, "processing step");
  h.setString("DATE", utcNowIso(), "UTC time the file was written");
  for (const auto& c : parameters.cards)
    h.cards.push_back(c);
  return h;
}

}  // namespace st::io

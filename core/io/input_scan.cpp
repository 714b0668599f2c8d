#include "input_scan.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <utility>

#include "fits_file.hpp"
#include "rice_check.hpp"
#include "st/common/error.hpp"
#include "st/common/units.hpp"
#include "st/io/fits_time.hpp"

namespace st::io::detail {
namespace {

namespace fs = std::filesystem;

bool looksLikeFits(const fs::path& p) {
  std::string name = p.filename().string();
  std::transform(name.begin(), name.end(), name.begin(), [](unsigned char c) { return std::tolower(c); });
  for (const char* ext :
       {".fits", ".fit", ".fts", ".fits.fz", ".fit.fz", ".fz", ".fits.gz", ".fit.gz", ".fts.gz"}) {
    const std::string e = ext;
    if (name.size() > e.size() && name.compare(name.size() - e.size(), e.size(), e) == 0) return true;
  }
  return false;
}

std::string hduName(const std::string& path, int hdu) {
  return path + " HDU " + std::to_string(hdu);
}

// Reads the planes' times from a binary table "FRAMES" (written by writeCube) when the file has one.
bool timesFromFramesTable(const FitsFile& f, ScannedFile& s) {
  int status = 0;
  const int imageHdu = f.currentHdu();
  char name[] = "FRAMES";
  fits_movnam_hdu(f.get(), BINARY_TBL, name, 0, &status);
  if (status != 0) {
    fits_clear_errmsg();
    status = 0;
    fits_movabs_hdu(f.get(), imageHdu, nullptr, &status);
    f.check(status, "returning to the image HDU");
    return false;
  }
  const std::string where = hduName(s.path, f.currentHdu()) + " (FRAMES table)";
  long rows = 0;
  fits_get_num_rows(f.get(), &rows, &status);
  f.check(status, "reading the FRAMES table size");
  if (rows != s.planes) {
    throw InputError(where + ": has " + std::to_string(rows) + " rows but the cube has " +
                     std::to_string(s.planes) + " planes (NAXIS3)");
  }
  int colMjd = 0;
  int colExp = 0;
  char mjdName[] = "MJD_MID";
  char expName[] = "EXPTIME";
  fits_get_colnum(f.get(), CASEINSEN, mjdName, &colMjd, &status);
  if (status != 0) throw InputError(where + ": has no column MJD_MID: " + cfitsioMessage(status));
  std::vector<double> mjd(static_cast<std::size_t>(rows)), exp(static_cast<std::size_t>(rows), NAN);
  int anynul = 0;
  double nan = NAN;
  fits_read_col(f.get(), TDOUBLE, colMjd, 1, 1, rows, &nan, mjd.data(), &anynul, &status);
  f.check(status, "reading column MJD_MID of the FRAMES table");
  fits_get_colnum(f.get(), CASEINSEN, expName, &colExp, &status);
  if (status == 0) {
    fits_read_col(f.get(), TDOUBLE, colExp, 1, 1, rows, &nan, exp.data(), &anynul, &status);
    f.check(status, "reading column EXPTIME of the FRAMES table");
  } else {
    fits_clear_errmsg();
    status = 0;
  }
  // Registration offsets (written when the frames were registered), optional.
  std::vector<double> regX(static_cast<std::size_t>(rows), 0.0), regY(static_cast<std::size_t>(rows), 0.0);
  for (auto [column, out] : {std::pair{"REGX_PX", &regX}, std::pair{"REGY_PX", &regY}}) {
    int col = 0;
    char colName[16];
    std::snprintf(colName, sizeof colName, "%s", column);
    fits_get_colnum(f.get(), CASEINSEN, colName, &col, &status);
    if (status != 0) {
      fits_clear_errmsg();
      status = 0;
      continue;
    }
    double zero = 0.0;
    fits_read_col(f.get(), TDOUBLE, col, 1, 1, rows, &zero, out->data(), &anynul, &status);
    f.check(status, std::string("reading column ") + name + " of the FRAMES table");
  }
  for (long r = 0; r < rows; ++r) {
    s.frames[r].offsetXPx = std::isfinite(regX[r]) ? regX[r] : 0.0;
    s.frames[r].offsetYPx = std::isfinite(regY[r]) ? regY[r] : 0.0;
    if (!std::isfinite(mjd[r]))
      throw InputError(where + ": row " + std::to_string(r + 1) + " has no MJD_MID");
    s.frames[r].mjdMid = mjdFromMjdOrJd(mjd[r]);
    if (std::isfinite(exp[r])) s.frames[r].exposureS = exp[r];
  }
  s.timeSource = "FRAMES table";
  fits_movabs_hdu(f.get(), imageHdu, nullptr, &status);
  f.check(status, "returning to the image HDU");
  return true;
}

// Per-plane keywords MJD_<n> / MJD<n> (n = 1-based plane), mid-times.
bool timesFromPlaneKeywords(ScannedFile& s) {
  const std::string where = hduName(s.path, s.hdu);
  for (const char* prefix : {"MJD_", "MJD"}) {
    if (!s.header.has(std::string(prefix) + "1")) continue;
    for (int n = 0; n < s.planes; ++n) {
      const std::string key = prefix + std::to_string(n + 1);
      std::optional<double> v;
      try {
        v = s.header.getDouble(key);
      } catch (const InputError& e) {
        throw InputError(where + ": " + e.what());
      }
      if (!v)
        throw InputError(where + ": per-plane time keyword " + key + " is missing (plane " +
                         std::to_string(n + 1) + ")");
      s.frames[n].mjdMid = mjdFromMjdOrJd(*v);
    }
    s.timeSource = std::string(prefix) + "<n> keywords";
    return true;
  }
  return false;
}

// First plane's time from the usual keywords plus a cadence: FRAMERAT/FRATE (Hz) or CADENCE/DELTAT (s).
void timesFromStartAndRate(ScannedFile& s) {
  const std::string where = hduName(s.path, s.hdu);
  const FrameTime t = frameTimeFromHeader(s.header, where);
  for (auto& f : s.frames)
    f.exposureS = t.exposureS;
  if (!t.mjdMid) return;
  if (s.planes == 1) {
    s.frames[0].mjdMid = t.mjdMid;
    s.timeSource = t.source;
    return;
  }
  std::optional<double> cadenceS;
  try {
    for (const char* key : {"FRAMERAT", "FRATE", "FRAMERATE"}) {
      if (auto hz = s.header.getDouble(key); hz && *hz > 0) cadenceS = 1.0 / *hz;
    }
    for (const char* key : {"CADENCE", "DELTAT", "FRAMETIM"}) {
      if (auto dt = s.header.getDouble(key); dt && *dt > 0) cadenceS = *dt;
    }
  } catch (const InputError& e) {
    throw InputError(where + ": " + e.what());
  }
  if (!cadenceS) return;  // a cube with one time and no cadence: treated as having no times
  for (int n = 0; n < s.planes; ++n)
    s.frames[n].mjdMid = *t.mjdMid + n * *cadenceS / kSecondsPerDay;
  s.timeSource = t.source + " + plane * cadence";
}

// "bias", "dark" or "flat" when IMAGETYP or OBSTYPE names a calibration frame (case-insensitive: 'Bias Frame',
// 'ZERO', 'dark', 'FLAT', 'Flat Field', 'SKYFLAT', ...); the card that said so goes to `card`.
std::optional<std::string> calibrationType(const FitsHeader& h, std::string& card) {
  for (const char* key : {"IMAGETYP", "OBSTYPE"}) {
    const auto v = h.getString(key);
    if (!v) continue;
    std::string lower = *v;
    std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return std::tolower(c); });
    const auto has = [&](const char* word) { return lower.find(word) != std::string::npos; };
    std::optional<std::string> type;
    if (has("bias") || has("zero")) {
      type = "bias";
    } else if (has("dark")) {
      type = "dark";
    } else if (has("flat")) {
      type = "flat";
    }
    if (type) {
      card = std::string(key) + " = '" + *v + "'";
      return type;
    }
  }
  return std::nullopt;
}

// A science input that is a calibration frame, or has no exposure, is most likely a mistake the user should
// see: it is stacked like any other frame.
void warnIfNotScience(ScannedFile& s) {
  std::string card;
  const auto type = calibrationType(s.header, card);
  const char* zeroExposure = nullptr;  // the keyword that says 0
  try {
    for (const char* key : {"EXPTIME", "EXPOSURE"}) {
      if (const auto e = s.header.getDouble(key)) {
        if (*e == 0.0) zeroExposure = key;
        break;
      }
    }
  } catch (const InputError&) {
    // not a number: reported where the times are read
  }
  if (!type && !zeroExposure) return;
  std::string what = hduName(s.path, s.hdu) + ": ";
  if (type) what += card + " says a " + *type + " frame";
  if (zeroExposure) what += std::string(type ? ", and " : "") + zeroExposure + " = 0 (no exposure)";
  what += ", given as a science frame (it is stacked like the others); leave it out of the science inputs "
          "(calibration frames go to preprocess --bias/--dark/--flat)";
  s.warnings.push_back(std::move(what));
}

}  // namespace

std::vector<std::string> expandInputs(const std::vector<std::string>& inputs) {
  std::vector<std::string> files;
  for (const auto& in : inputs) {
    std::error_code ec;
    if (fs::is_directory(in, ec)) {
      std::vector<std::string> inside;
      for (const auto& e : fs::directory_iterator(in, ec)) {
        if (e.is_regular_file() && looksLikeFits(e.path())) inside.push_back(e.path().string());
      }
      if (inside.empty()) throw InputError(in + ": folder has no FITS files (.fits, .fit, .fts, .fz, .gz)");
      std::sort(inside.begin(), inside.end());
      files.insert(files.end(), inside.begin(), inside.end());
    } else if (fs::exists(in, ec)) {
      files.push_back(in);
    } else {
      throw InputError(in + ": file not found");
    }
  }
  if (files.empty()) throw InputError("no input files given (zero frames)");
  return files;
}

void selectImageHdu(const FitsFile& f, const std::optional<std::string>& hdu) {
  int status = 0;
  if (hdu) {
    int n = 0;
    const auto [ptr, ec] = std::from_chars(hdu->data(), hdu->data() + hdu->size(), n);
    if (ec == std::errc() && ptr == hdu->data() + hdu->size()) {
      int nhdus = 0;
      fits_get_num_hdus(f.get(), &nhdus, &status);
      if (n < 1 || n > nhdus) {
        throw InputError(f.path() + ": HDU " + *hdu + " does not exist (the file has " +
                         std::to_string(nhdus) + " HDUs, numbered from 1 = primary)");
      }
      fits_movabs_hdu(f.get(), n, nullptr, &status);
      f.check(status, "moving to HDU " + *hdu);
    } else {
      std::string name = *hdu;
      fits_movnam_hdu(f.get(), IMAGE_HDU, name.data(), 0, &status);
      if (status != 0) {
        fits_clear_errmsg();
        throw InputError(f.path() + ": has no image HDU named '" + *hdu + "' (EXTNAME)");
      }
    }
    return;
  }
  for (int n = 1;; ++n) {
    int type = 0;
    status = 0;
    fits_movabs_hdu(f.get(), n, &type, &status);
    if (status == END_OF_FILE && n > 1) {
      fits_clear_errmsg();
      throw InputError(f.path() + ": has no image HDU with data (zero frames)");
    }
    f.check(status, "moving to HDU " + std::to_string(n));
    if (type != IMAGE_HDU) continue;
    int naxis = 0;
    fits_get_img_dim(f.get(), &naxis, &status);
    f.check(status, "reading NAXIS");
    if (naxis == 0) continue;
    return;
  }
}

ScannedFile scanFile(const std::string& path, std::size_t fileIndex, const LoadOptions& options) {
  FitsFile f = FitsFile::openRead(path);
  selectImageHdu(f, options.hdu);
  ScannedFile s;
  s.path = path;
  s.hdu = f.currentHdu();
  const std::string where = hduName(path, s.hdu);
  int status = 0;
  int naxis = 0;
  long naxes[9] = {};
  int rawBitpix = 0;
  fits_get_img_param(f.get(), 9, &rawBitpix, &naxis, naxes, &status);
  f.check(status, "reading BITPIX/NAXIS");
  fits_get_img_equivtype(f.get(), &s.bitpix, &status);
  f.check(status, "reading BITPIX/BZERO");
  if (naxis < 2 || naxis > 9) {
    throw InputError(where + ": NAXIS = " + std::to_string(naxis) + "; expected a 2-D image or a 3-D cube");
  }
  for (int a = 3; a < naxis; ++a) {
    if (naxes[a] != 1) {
      throw InputError(where + ": NAXIS = " + std::to_string(naxis) + " with NAXIS" + std::to_string(a + 1) +
                       " = " + std::to_string(naxes[a]) + "; expected a 2-D image or a 3-D cube");
    }
  }
  if (naxes[0] <= 0 || naxes[1] <= 0 || (naxis >= 3 && naxes[2] <= 0)) {
    throw InputError(where + ": image has no pixels (NAXIS1 x NAXIS2 x NAXIS3 = " + std::to_string(naxes[0]) +
                     " x " + std::to_string(naxes[1]) + " x " + std::to_string(naxis >= 3 ? naxes[2] : 1) +
                     "; zero frames)");
  }
  if (naxes[0] > 1000000 || naxes[1] > 1000000 || naxes[2] > 100000000) {
    throw InputError(where + ": implausible image size NAXIS1 = " + std::to_string(naxes[0]) +
                     ", NAXIS2 = " + std::to_string(naxes[1]));
  }
  s.width = static_cast<int>(naxes[0]);
  s.height = static_cast<int>(naxes[1]);
  s.planes = naxis >= 3 ? static_cast<int>(naxes[2]) : 1;
  // Truncated uncompressed files are caught here, before any pixel is read. A plain (not gzip'ed) file
  // also gets the data offset for the direct float32 read path.
  const int compressed = fits_is_compressed_image(f.get(), &status);
  if (!compressed) {
    LONGLONG headStart = 0, dataStart = 0, dataEnd = 0;
    fits_get_hduaddrll(f.get(), &headStart, &dataStart, &dataEnd, &status);
    f.check(status, "locating the data");
    const LONGLONG bytes = static_cast<LONGLONG>(std::abs(rawBitpix) / 8) * naxes[0] * naxes[1] * s.planes;
    std::error_code ec;
    const auto fileSize = static_cast<LONGLONG>(std::filesystem::file_size(path, ec));
    char magic[6] = {};
    std::ifstream(path, std::ios::binary).read(magic, sizeof magic);
    const bool plain = std::string_view(magic, 6) == "SIMPLE";
    if (plain && !ec && dataStart + bytes > fileSize) {
      throw InputError(where + ": file is truncated: the image needs " + std::to_string(dataStart + bytes) +
                       " bytes, the file has " + std::to_string(fileSize));
    }
    if (plain && rawBitpix == FLOAT_IMG) s.rawFloatOffset = dataStart;
  }
  checkRiceTiles(f);  // before CFITSIO decompresses anything (it crashes on corrupt RICE tiles)
  s.header = readHeader(f);
  if (options.scienceFrames) warnIfNotScience(s);
  try {
    if (s.header.getDouble("BZERO").value_or(0.0) != 0.0 ||
        s.header.getDouble("BSCALE").value_or(1.0) != 1.0) {
      s.rawFloatOffset = -1;  // scaled floats go through CFITSIO
    }
  } catch (const InputError& e) {
    throw InputError(where + ": " + e.what());
  }
  s.frames.resize(static_cast<std::size_t>(s.planes));
  for (int n = 0; n < s.planes; ++n) {
    s.frames[n].fileIndex = fileIndex;
    s.frames[n].plane = n;
  }
  if (s.planes > 1 && (timesFromFramesTable(f, s) || timesFromPlaneKeywords(s))) {
    const FrameTime t = frameTimeFromHeader(s.header, where);
    for (auto& fr : s.frames) {
      if (!fr.exposureS) fr.exposureS = t.exposureS;
    }
    return s;
  }
  timesFromStartAndRate(s);
  return s;
}

}  // namespace st::io::detail

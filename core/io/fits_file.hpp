#pragma once
// Internal to core/io: an owning CFITSIO handle and helpers shared by the reader and the writer. A FitsFile
// is used by one thread only (ARCHITECTURE.md: a fitsfile* is never shared between threads).
#include <fitsio.h>

#include <string>

#include "st/common/fits_header.hpp"

namespace st::io::detail {

/// CFITSIO's text for `status` plus the messages on its error stack (which the call clears).
std::string cfitsioMessage(int status);

class FitsFile {
 public:
  /// Opens `path` read-only without CFITSIO's extended file-name syntax (so "[", "(" in names are literal).
  /// Throws st::InputError for a missing file, st::FitsError naming the file when it is not FITS.
  static FitsFile openRead(const std::string& path);
  /// Creates (overwriting) `path`. Throws st::FitsError.
  static FitsFile create(const std::string& path);
  FitsFile(FitsFile&& other) noexcept;
  FitsFile& operator=(FitsFile&&) = delete;
  FitsFile(const FitsFile&) = delete;
  FitsFile& operator=(const FitsFile&) = delete;
  ~FitsFile();

  fitsfile* get() const noexcept { return m_fptr; }
  const std::string& path() const noexcept { return m_path; }
  /// 1-based number of the current HDU.
  int currentHdu() const;
  /// Throws st::FitsError "<file> HDU n: <what>: <CFITSIO text>" when status != 0.
  void check(int status, const std::string& what) const;
  /// Closes now, reporting a failure (writers must call this to see flush errors).
  void close();

 private:
  FitsFile(fitsfile* f, std::string path) : m_fptr(f), m_path(std::move(path)) {}
  fitsfile* m_fptr = nullptr;
  std::string m_path;
};

/// The header of the current HDU; for a tile-compressed image, the header of the uncompressed image.
FitsHeader readHeader(const FitsFile& file);

/// Parses `ncards` 80-character cards (CFITSIO/wcslib header text) into a FitsHeader.
FitsHeader parseHeaderText(const char* text, int ncards);

}  // namespace st::io::detail

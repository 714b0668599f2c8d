#pragma once
// Internal to core/io: finding the input files and reading their headers (no pixels), so that sizes and
// times can be checked before a single pixel is loaded (nothing half-loaded).
#include <optional>
#include <string>
#include <vector>

#include "st/common/fits_header.hpp"
#include "st/io/fits_reader.hpp"

namespace st::io::detail {

/// One image plane to load.
struct PlaneRef {
  std::size_t fileIndex = 0;     ///< index into the scanned files
  int plane = 0;                 ///< 0-based plane of a 3-D HDU (0 for 2-D)
  std::optional<double> mjdMid;  ///< from the headers/table; empty when unknown
  std::optional<double> exposureS;
  double offsetXPx = 0.0;  ///< registration offset from a FRAMES table's REGX_PX/REGY_PX (FrameInfo)
  double offsetYPx = 0.0;
};

/// One file's chosen image HDU, described from its header only.
struct ScannedFile {
  std::string path;
  int hdu = 0;  ///< 1-based
  int width = 0;
  int height = 0;
  int planes = 0;
  int bitpix = 0;  ///< equivalent BITPIX (BZERO 32768 on 16 bits reads as 20 = unsigned 16)
  FitsHeader header;
  /// Byte offset of the data of an unscaled BITPIX -32 image in a plain file (read directly, big-endian
  /// floats); -1 when CFITSIO must convert (other types, scaling, compression, gzip).
  long long rawFloatOffset = -1;
  std::string timeSource;
  std::vector<PlaneRef> frames;
  std::vector<std::string> warnings;
};

/// Expands folders (FITS files inside, sorted by name) and checks every file exists. Throws st::InputError.
std::vector<std::string> expandInputs(const std::vector<std::string>& inputs);

/// Reads the header of the chosen image HDU of `path` and the frame times. Throws st::InputError /
/// st::FitsError naming the file, HDU and keyword.
ScannedFile scanFile(const std::string& path, std::size_t fileIndex, const LoadOptions& options);

/// Moves to the image HDU `options.hdu` names, or the first image HDU with data. Throws naming the file.
void selectImageHdu(const class FitsFile& file, const std::optional<std::string>& hdu);

}  // namespace st::io::detail

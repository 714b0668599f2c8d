#pragma once
// Copying a FITS file HDU by HDU while adding an image to some of its image planes: what `synthtrack-cli
// inject` needs to write copies of raw frames that keep their layout and headers. Tile-compressed images
// (.fz) are written uncompressed at the same HDU number (CFITSIO's fits_img_decompress: same header cards,
// same BITPIX/BZERO); every other HDU is copied byte for byte.
#include <string>
#include <vector>

#include "st/common/fits_header.hpp"
#include "st/common/image.hpp"

namespace st::io {

/// An image to add to one plane of one image HDU.
struct PlaneAddition {
  int hdu = 1;                ///< 1-based HDU number (CFITSIO's numbering), as FrameInfo::hdu
  int plane = 0;              ///< 0-based plane of a 3-D image (0 for a 2-D image)
  const Image* add = nullptr; ///< same size as the plane, in the file's physical units (BZERO/BSCALE applied)
};

/// What copyWithAddedPixels did.
struct CopyReport {
  std::size_t clippedPixels = 0;  ///< sums outside the range of an integer BITPIX, set to its limit
  int hdus = 0;                   ///< HDUs copied
};

/// Copies `src` to `dst` (overwritten), adding each `additions` image to its plane. Integer images get the
/// sum rounded to the nearest integer and clipped to the range of their type (BITPIX with BZERO, e.g. 0 to
/// 65535 for unsigned 16-bit); null (BLANK/NaN) pixels are left null. The edited HDUs also get `cards`
/// (set or replaced) and `history` as HISTORY cards; HDUs whose data or header changed get a fresh
/// CHECKSUM/DATASUM when they had one. Throws st::InputError / st::FitsError naming the file and HDU (an
/// addition whose HDU is not an image or whose size differs from the plane's).
CopyReport copyWithAddedPixels(const std::string& src, const std::string& dst,
                               const std::vector<PlaneAddition>& additions, const FitsHeader& cards = {},
                               const std::vector<std::string>& history = {});

}  // namespace st::io

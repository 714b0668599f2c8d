#pragma once
// Writing FITS: cubes (with a table of frame times) and 2-D stacks, with the WCS and provenance keywords
// (software version, parameters, velocity, reference epoch). astropy reads them with equal pixels and
// header values (tests/python). Pixels are converted to FITS's 1-based convention here and nowhere else.
#include <memory>
#include <string>
#include <string_view>

#include "st/common/fits_header.hpp"
#include "st/common/frame_cube.hpp"
#include "st/common/image.hpp"

namespace st::io {

/// Writes the cube as one 3-D float32 image HDU (NAXIS3 = frames) with the first frame's header cards
/// (structural keywords replaced), `extra` cards, and a binary table extension "FRAMES" with each frame's
/// MJD mid-time, exposure and origin. Overwrites `path`. Throws st::FitsError.
///
/// Card values keep their types: numbers are written as numbers, logicals as T/F, strings quoted; WCS cards
/// come from cube.wcs->toHeader() when the cube has a WCS (so quoted-number WCS values become numbers).
/// Masked pixels (cube.mask()) are written as NaN. FRAMES columns: MJD_MID (D, day, UTC mid-exposure),
/// EXPTIME (D, s), FILE (A), HDU (J, 1-based), PLANE (J, 0-based). loadFrames reads the times back.
void writeCube(const std::string& path, const FrameCube& cube, const FitsHeader& extra = {});

/// A cube written piece by piece (out-of-core pre-processing, issue 20): the file is created with its size
/// and header, each call writes a rectangle of every frame (CFITSIO's subset writer), finish() appends the
/// FRAMES table and closes. The file is what writeCube writes for the whole cube. Not copyable; one thread.
class CubeRegionWriter {
 public:
  /// Creates `path` (overwriting) as a width x height x frames float32 cube with `header`'s cards (the
  /// structural ones replaced), the WCS `wcs` when not null and `extra`. Throws st::FitsError.
  CubeRegionWriter(const std::string& path, int width, int height, std::size_t frames, const FitsHeader& header,
                   const Wcs* wcs, const FitsHeader& extra);
  CubeRegionWriter(const CubeRegionWriter&) = delete;
  CubeRegionWriter& operator=(const CubeRegionWriter&) = delete;
  ~CubeRegionWriter();

  /// Writes rows [srcY0, srcY0 + rows) and columns [srcX0, srcX0 + cols) of every frame of `region` (which
  /// has the cube's frame count) at (x0, y0) of the cube (0-based). Masked samples are written as NaN.
  /// Throws st::InputError when the rectangle leaves either cube, st::FitsError.
  void write(const FrameCube& region, int srcX0, int srcY0, int cols, int rows, int x0, int y0);
  /// Updates (or adds) a card of the primary header (values known only at the end, e.g. SIGMAF).
  void updateCards(const FitsHeader& cards);
  /// Appends the FRAMES table from `frames`' FrameInfo (times, origins, registration offsets) and closes.
  void finish(const FrameCube& frames);

 private:
  struct Impl;
  std::unique_ptr<Impl> m_impl;
};

/// Writes one 2-D float32 image with `header` cards (e.g. a WCS and provenance). Overwrites `path`.
void writeImage(const std::string& path, const Image& image, const FitsHeader& header = {});

/// Cards recording provenance: SOFTWARE = "synthtrack x.y.z", STEP = `step`, DATE = the UTC time of the call
/// (ISO 8601), followed by `parameters` (cards the caller names, keys of at most 8 characters, e.g.
/// VX_PXS = 1.25 / velocity x px/s; REFEPOCH = 60000.1 / t_ref MJD).
FitsHeader provenanceCards(const std::string& step, const FitsHeader& parameters = {});

/// Header keywords that describe the data layout (SIMPLE, BITPIX, NAXISn, BZERO, BSCALE, BLANK,
/// tile-compression Z*, table T* keywords, CHECKSUM, ...): the writers drop them from copied headers and
/// write their own.
bool isStructuralKeyword(std::string_view key);

}  // namespace st::io

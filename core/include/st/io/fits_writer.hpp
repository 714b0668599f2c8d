#pragma once
// Writing FITS: cubes (with a table of frame times) and 2-D stacks, with the WCS and provenance keywords
// (software version, parameters, velocity, reference epoch). astropy reads them with equal pixels and
// header values (tests/python). Pixels are converted to FITS's 1-based convention here and nowhere else.
#include <string>

#include "st/common/fits_header.hpp"
#include "st/common/frame_cube.hpp"
#include "st/common/image.hpp"

namespace st::io {

/// Writes the cube as one 3-D float32 image HDU (NAXIS3 = frames) with the first frame's header cards
/// (structural keywords replaced), `extra` cards, and a binary table extension "FRAMES" with each frame's
/// MJD mid-time, exposure and origin. Overwrites `path`. Throws st::FitsError.
void writeCube(const std::string& path, const FrameCube& cube, const FitsHeader& extra = {});

/// Writes one 2-D float32 image with `header` cards (e.g. a WCS and provenance). Overwrites `path`.
void writeImage(const std::string& path, const Image& image, const FitsHeader& header = {});

/// Cards recording provenance: SOFTWARE = "synthtrack x.y.z", STEP, and the given parameters.
FitsHeader provenanceCards(const std::string& step);

}  // namespace st::io

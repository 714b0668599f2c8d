#pragma once
// Image sections (BIASSEC, TRIMSEC) for calibration: the io stage's parser (st/io/sections.hpp), plus the
// check that a section fits the frames it is applied to.
#include <string_view>

#include "st/io/sections.hpp"

namespace st::calib {

/// A 0-based rectangle of pixels (x0, y0, width, height).
using Section = io::PixelRegion;

/// Throws st::InputError naming `keyword`, the section (1-based, as in the header) and the frame size when
/// the section does not lie inside a width x height frame.
void checkSectionInside(const Section& s, int width, int height, std::string_view keyword);

}  // namespace st::calib

#pragma once
// Image sections (BIASSEC, TRIMSEC) for calibration: the io stage's parser (st/io/sections.hpp), plus the
// check that a section fits the frames it is applied to.
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "st/io/sections.hpp"

namespace st::calib {

/// A 0-based rectangle of pixels (x0, y0, width, height).
using Section = io::PixelRegion;

/// Throws st::InputError naming `keyword`, the section (1-based, as in the header) and the frame size when
/// the section does not lie inside a width x height frame. For sections a person gave explicitly.
void checkSectionInside(const Section& s, int width, int height, std::string_view keyword);

/// A section read from a header, made to fit a width x height frame: itself when it lies inside; else the
/// part inside, with a warning; nullopt, with a warning, when no part is inside. Odd headers are never a
/// dead end (a sub-framed readout keeps the full detector's BIASSEC, say). Warnings name `file` and
/// `keyword` and are appended to `warnings`.
std::optional<Section> fitSectionToFrame(const Section& s, int width, int height, std::string_view keyword,
                                         std::string_view file, std::vector<std::string>& warnings);

}  // namespace st::calib

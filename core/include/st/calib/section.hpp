#pragma once
// IRAF-style image sections in FITS headers (BIASSEC, TRIMSEC, DATASEC): "[x1:x2,y1:y2]", 1-based and
// inclusive, blanks tolerated. Converted to 0-based here (ARCHITECTURE.md: 1-based only at the FITS edge).
// A small parser local to calib until st/io/sections.hpp lands on main.
#include <string>
#include <string_view>

namespace st::calib {

struct Section {
  int x0 = 0;  ///< 0-based first column
  int y0 = 0;  ///< 0-based first row
  int width = 0;
  int height = 0;
  friend bool operator==(const Section&, const Section&) = default;
};

/// Parses "[x1:x2,y1:y2]" (1-based, inclusive; reversed ranges are accepted and normalised). Throws
/// st::InputError naming `keyword` and the text when it is malformed.
Section parseSection(std::string_view text, std::string_view keyword);

/// Throws st::InputError naming `keyword`, the section and the frame size when the section does not lie
/// inside a width x height frame.
void checkSectionInside(const Section& s, int width, int height, std::string_view keyword);

}  // namespace st::calib

#pragma once
// FITS image sections such as TRIMSEC = '[18:1382,1:1370]' or BIASSEC = '[  4:  13,   1: 520]' (IRAF
// convention: 1-based, inclusive, x = column range first), turned into 0-based pixel regions
// (ARCHITECTURE.md, "Pixels").
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "st/common/fits_header.hpp"

namespace st::io {

/// A rectangle of pixels, 0-based (x0 = first column, y0 = first row), width x height pixels.
struct PixelRegion {
  int x0 = 0;
  int y0 = 0;
  int width = 0;
  int height = 0;
  friend bool operator==(const PixelRegion&, const PixelRegion&) = default;
};

/// Parses "[x1:x2,y1:y2]" (1-based, inclusive; blanks anywhere allowed; reversed ranges such as
/// "[100:1,1:50]" are accepted and normalised) into a 0-based region. Throws st::InputError naming
/// `keyword` and the text when the text is not a 2-D section or a bound is below 1.
PixelRegion parseSection(std::string_view text, std::string_view keyword = "section");

/// The section in header keyword `keyword` (e.g. "TRIMSEC"), or nullopt when absent or blank.
/// Throws st::InputError (naming the keyword) when present but malformed.
std::optional<PixelRegion> sectionFromHeader(const FitsHeader& header, std::string_view keyword);

/// The image-section keywords that describe the frame's own pixels (IRAF convention): the overscan, the
/// part to keep, the data. Not CCDSEC/DETSEC, which are in detector coordinates.
inline constexpr std::string_view kImageSectionKeywords[] = {"BIASSEC", "TRIMSEC", "DATASEC"};

/// "[x1:x2,y1:y2]" (1-based, inclusive), the inverse of parseSection.
std::string formatSection(const PixelRegion& r);

/// The part of `r` inside a width x height frame, or nullopt when none of it is.
std::optional<PixelRegion> clipRegion(const PixelRegion& r, int width, int height);

/// Makes the image sections of `header` (kImageSectionKeywords) describe a frame cropped to `crop` (0-based,
/// in the original frame's pixels): each is moved by the crop's origin and clipped to the crop. A section
/// that is partly outside the crop is cut to it, with a warning; one that is wholly outside, or that is not
/// a valid section, is removed, with a warning. Warnings name `file` and the keyword and are appended to
/// `warnings`; sections wholly inside are moved silently.
void cropSections(FitsHeader& header, const PixelRegion& crop, std::string_view file,
                  std::vector<std::string>& warnings);

}  // namespace st::io

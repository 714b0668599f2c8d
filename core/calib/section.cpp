#include "st/calib/section.hpp"

#include <string>

#include "st/common/error.hpp"

namespace st::calib {

namespace {

bool inside(const Section& s, int width, int height) {
  return s.x0 >= 0 && s.y0 >= 0 && s.width > 0 && s.height > 0 && s.x0 + s.width <= width &&
         s.y0 + s.height <= height;
}

std::string sizeText(int width, int height) {
  return std::to_string(width) + "x" + std::to_string(height);
}

}  // namespace

void checkSectionInside(const Section& s, int width, int height, std::string_view keyword) {
  if (!inside(s, width, height)) {
    throw InputError(std::string(keyword) + " " + io::formatSection(s) + " does not fit frames of " +
                     sizeText(width, height));
  }
}

std::optional<Section> fitSectionToFrame(const Section& s, int width, int height, std::string_view keyword,
                                         std::string_view file, std::vector<std::string>& warnings) {
  if (inside(s, width, height)) return s;
  const std::string what = std::string(file) + ": " + std::string(keyword) + " " + io::formatSection(s) +
                           " does not fit frames of " + sizeText(width, height);
  const std::optional<Section> clipped = io::clipRegion(s, width, height);
  if (!clipped) {
    warnings.push_back(what + "; ignored");
    return std::nullopt;
  }
  warnings.push_back(what + "; clipped to " + io::formatSection(*clipped));
  return clipped;
}

}  // namespace st::calib

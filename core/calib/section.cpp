#include "st/calib/section.hpp"

#include <string>

#include "st/common/error.hpp"

namespace st::calib {

void checkSectionInside(const Section& s, int width, int height, std::string_view keyword) {
  if (s.x0 < 0 || s.y0 < 0 || s.width <= 0 || s.height <= 0 || s.x0 + s.width > width ||
      s.y0 + s.height > height) {
    throw InputError(std::string(keyword) + " [" + std::to_string(s.x0 + 1) + ":" +
                     std::to_string(s.x0 + s.width) + "," + std::to_string(s.y0 + 1) + ":" +
                     std::to_string(s.y0 + s.height) + "] does not fit frames of " + std::to_string(width) +
                     "x" + std::to_string(height));
  }
}

}  // namespace st::calib

#include "st/calib/section.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>

#include "st/common/error.hpp"

namespace st::calib {

Section parseSection(std::string_view text, std::string_view keyword) {
  std::string s;
  for (char c : text)
    if (!std::isspace(static_cast<unsigned char>(c))) s.push_back(c);
  auto fail = [&]() -> Section {
    throw InputError(std::string(keyword) + " = '" + std::string(text) +
                     "' is not an image section of the form [x1:x2,y1:y2]");
  };
  if (s.size() < 9 || s.front() != '[' || s.back() != ']') return fail();
  int v[4];
  const char* p = s.data() + 1;
  const char* end = s.data() + s.size() - 1;
  const char seps[4] = {':', ',', ':', ']'};
  for (int i = 0; i < 4; ++i) {
    auto [q, ec] = std::from_chars(p, end, v[i]);
    if (ec != std::errc() || v[i] < 1) return fail();
    if (i < 3 && (q >= end || *q != seps[i])) return fail();
    if (i == 3 && q != end) return fail();
    p = q + 1;
  }
  Section out;
  out.x0 = std::min(v[0], v[1]) - 1;
  out.width = std::abs(v[1] - v[0]) + 1;
  out.y0 = std::min(v[2], v[3]) - 1;
  out.height = std::abs(v[3] - v[2]) + 1;
  return out;
}

void checkSectionInside(const Section& s, int width, int height, std::string_view keyword) {
  if (s.x0 < 0 || s.y0 < 0 || s.width <= 0 || s.height <= 0 || s.x0 + s.width > width ||
      s.y0 + s.height > height) {
    throw InputError(std::string(keyword) + " [" + std::to_string(s.x0 + 1) + ":" +
                     std::to_string(s.x0 + s.width) + "," + std::to_string(s.y0 + 1) + ":" +
                     std::to_string(s.y0 + s.height) + "] does not fit frames of " + std::to_string(width) + "x" +
                     std::to_string(height));
  }
}

}  // namespace st::calib

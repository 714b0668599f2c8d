#include "st/io/sections.hpp"

#include <algorithm>
#include <charconv>
#include <string>

#include "st/common/error.hpp"

namespace st::io {
namespace {

[[noreturn]] void bad(std::string_view keyword, std::string_view text, const std::string& why) {
  throw InputError("header keyword " + std::string(keyword) + " = '" + std::string(text) +
                   "' is not an image section [x1:x2,y1:y2]: " + why);
}

}  // namespace

PixelRegion parseSection(std::string_view text, std::string_view keyword) {
  std::string s;
  for (char c : text) {
    if (c != ' ' && c != '\t') s += c;
  }
  if (s.size() < 2 || s.front() != '[' || s.back() != ']') bad(keyword, text, "missing brackets");
  s = s.substr(1, s.size() - 2);
  long v[4] = {};
  const char* p = s.data();
  const char* end = s.data() + s.size();
  const char seps[4] = {':', ',', ':', '\0'};
  for (int i = 0; i < 4; ++i) {
    const auto [ptr, ec] = std::from_chars(p, end, v[i]);
    if (ec != std::errc() || ptr == p)
      bad(keyword, text, "expected a number at position " + std::to_string(i + 1));
    p = ptr;
    if (i < 3) {
      if (p == end || *p != seps[i]) bad(keyword, text, std::string("expected '") + seps[i] + "'");
      ++p;
    }
  }
  if (p != end) bad(keyword, text, "unexpected text after the last number");
  for (long x : v) {
    if (x < 1 || x > 1000000000L) bad(keyword, text, "bounds must be 1-based and positive");
  }
  PixelRegion r;
  r.x0 = static_cast<int>(std::min(v[0], v[1]) - 1);
  r.width = static_cast<int>(std::max(v[0], v[1]) - std::min(v[0], v[1]) + 1);
  r.y0 = static_cast<int>(std::min(v[2], v[3]) - 1);
  r.height = static_cast<int>(std::max(v[2], v[3]) - std::min(v[2], v[3]) + 1);
  return r;
}

std::optional<PixelRegion> sectionFromHeader(const FitsHeader& header, std::string_view keyword) {
  const auto text = header.getString(keyword);
  if (!text || text->find_first_not_of(" \t") == std::string::npos) return std::nullopt;
  return parseSection(*text, keyword);
}

}  // namespace st::io

#include "st/io/sections.hpp"

#include <algorithm>
#include <charconv>
#include <cstdio>
#include <string>

#include "st/common/error.hpp"

namespace st::io {
namespace {

// `keyword` is a header keyword (TRIMSEC) or a command-line option (--crop).
[[noreturn]] void bad(std::string_view keyword, std::string_view text, const std::string& why) {
  const std::string what = keyword.substr(0, 2) == "--" ? "option " : "header keyword ";
  throw InputError(what + std::string(keyword) + " = '" + std::string(text) +
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

std::string formatSection(const PixelRegion& r) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "[%d:%d,%d:%d]", r.x0 + 1, r.x0 + r.width, r.y0 + 1, r.y0 + r.height);
  return buf;
}

std::optional<PixelRegion> clipRegion(const PixelRegion& r, int width, int height) {
  const long x0 = std::max<long>(0, r.x0), y0 = std::max<long>(0, r.y0);
  const long x1 = std::min<long>(width, static_cast<long>(r.x0) + r.width);
  const long y1 = std::min<long>(height, static_cast<long>(r.y0) + r.height);
  if (r.width <= 0 || r.height <= 0 || x1 <= x0 || y1 <= y0) return std::nullopt;
  return PixelRegion{static_cast<int>(x0), static_cast<int>(y0), static_cast<int>(x1 - x0),
                     static_cast<int>(y1 - y0)};
}

void cropSections(FitsHeader& header, const PixelRegion& crop, std::string_view file,
                  std::vector<std::string>& warnings) {
  const std::string cropText = formatSection(crop);
  for (std::string_view key : kImageSectionKeywords) {
    std::optional<PixelRegion> s;
    try {
      s = sectionFromHeader(header, key);
    } catch (const InputError& e) {
      warnings.push_back(std::string(file) + ": " + e.what() + "; ignored");
      header.erase(key);
      continue;
    }
    if (!s) continue;
    const std::string original = formatSection(*s);
    const PixelRegion moved{s->x0 - crop.x0, s->y0 - crop.y0, s->width, s->height};
    const std::optional<PixelRegion> inside = clipRegion(moved, crop.width, crop.height);
    if (!inside) {
      warnings.push_back(std::string(file) + ": " + std::string(key) + " " + original +
                         " lies outside the crop " + cropText + "; ignored");
      header.erase(key);
      continue;
    }
    if (!(*inside == moved)) {
      warnings.push_back(
          std::string(file) + ": " + std::string(key) + " " + original + " reaches outside the crop " +
          cropText + "; clipped to " +
          formatSection({inside->x0 + crop.x0, inside->y0 + crop.y0, inside->width, inside->height}) +
          " of the original frame");
    }
    header.setString(std::string(key), formatSection(*inside));
  }
}

}  // namespace st::io

#include "st/common/fits_header.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cstdio>

#include "st/common/error.hpp"

namespace st {
namespace {

bool equalsIgnoreCase(std::string_view a, std::string_view b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
           return std::toupper(static_cast<unsigned char>(x)) == std::toupper(static_cast<unsigned char>(y));
         });
}

std::string trim(std::string_view s) {
  const auto first = s.find_first_not_of(" \t'");
  if (first == std::string_view::npos) return {};
  const auto last = s.find_last_not_of(" \t'");
  return std::string(s.substr(first, last - first + 1));
}

}  // namespace

const FitsCard* FitsHeader::find(std::string_view key) const {
  for (const auto& c : cards) {
    if (equalsIgnoreCase(c.key, key)) return &c;
  }
  return nullptr;
}

std::optional<std::string> FitsHeader::getString(std::string_view key) const {
  const FitsCard* c = find(key);
  if (c == nullptr) return std::nullopt;
  return trim(c->value);
}

std::optional<double> FitsHeader::getDouble(std::string_view key) const {
  const auto text = getString(key);
  if (!text) return std::nullopt;
  std::string s = *text;
  // FITS allows 'D' as the exponent letter (Fortran style).
  std::replace(s.begin(), s.end(), 'D', 'E');
  std::replace(s.begin(), s.end(), 'd', 'e');
  if (!s.empty() && s.front() == '+') s.erase(0, 1);
  double v = 0.0;
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || ptr != s.data() + s.size()) {
    throw InputError("header keyword " + std::string(key) + " = '" + *text + "' is not a number");
  }
  return v;
}

void FitsHeader::set(std::string key, std::string value, std::string comment, bool isString) {
  for (auto& c : cards) {
    if (equalsIgnoreCase(c.key, key)) {
      c.value = std::move(value);
      if (!comment.empty()) c.comment = std::move(comment);
      c.isString = isString;
      return;
    }
  }
  cards.push_back(FitsCard{std::move(key), std::move(value), std::move(comment), isString});
}

void FitsHeader::setNumber(std::string key, double value, std::string comment) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.17g", value);
  set(std::move(key), buf, std::move(comment), false);
}

void FitsHeader::erase(std::string_view key) {
  std::erase_if(cards, [&](const FitsCard& c) { return equalsIgnoreCase(c.key, key); });
}

}  // namespace st

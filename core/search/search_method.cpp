#include "st/search/search_method.hpp"

#include <ostream>

namespace st::search {

SearchMethod::SearchMethod(std::string_view name) noexcept
    : m_value(parseSearchMethod(name).value_or(SearchMethod(Value::Unknown)).operator Value()) {}

std::string_view SearchMethod::name() const noexcept {
  return searchMethodName(*this);
}

std::string_view searchMethodName(SearchMethod method) noexcept {
  switch (method) {
    case SearchMethod::Exact:
      return "exact";
    case SearchMethod::Tree:
      return "tree";
    case SearchMethod::Auto:
      return "auto";
    case SearchMethod::Unknown:
      break;
  }
  return "unknown";
}

std::optional<SearchMethod> parseSearchMethod(std::string_view name) noexcept {
  if (name == "exact") return SearchMethod::Exact;
  if (name == "tree") return SearchMethod::Tree;
  if (name == "auto") return SearchMethod::Auto;
  return std::nullopt;
}

std::ostream& operator<<(std::ostream& out, SearchMethod method) {
  return out << method.name();
}

}  // namespace st::search

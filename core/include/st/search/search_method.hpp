#pragma once
// The velocity search's method, a typed choice (issue 18 item 3): SearchParams::method (what is asked),
// MethodChoice::method and SearchResult::method (what ran). Its names ("exact", "tree", "auto") are what
// files, the command line and sessions carry; searchMethodName() and parseSearchMethod() are the one place
// that maps between the two.
//
// SearchMethod is an enum wrapped in a class so that it can also be built from a name: code written before
// the enum (`params.method = "tree"`, `result.method == "tree"`, in files other people own: core/pipeline,
// gpu/bench, tests/gpu) keeps compiling and behaving. New code uses the values (SearchMethod::Tree) and
// parseSearchMethod() where text enters. A name that is no method gives SearchMethod::Unknown, which every
// backend and chooseMethod() refuse with an st::InputError, as they refused the unknown text before.
#include <cstdint>
#include <iosfwd>
#include <optional>
#include <string>
#include <string_view>

namespace st::search {

class SearchMethod {
 public:
  /// Scoped, so that a method never turns into a number or a character silently (`std::string s = method`
  /// does not compile; use name()).
  enum class Value : std::uint8_t {
    Exact,   ///< IPSA at every frame: the reference (ipsa.hpp)
    Tree,    ///< hierarchical shift-and-add (tree_search.hpp)
    Auto,    ///< resolved to Exact or Tree by chooseMethod (method_choice.hpp) before a backend sees it
    Unknown  ///< text that names no method (the name constructor only); refused where the method is used
  };
  static constexpr Value Exact = Value::Exact;
  static constexpr Value Tree = Value::Tree;
  static constexpr Value Auto = Value::Auto;
  static constexpr Value Unknown = Value::Unknown;

  constexpr SearchMethod() noexcept = default;
  constexpr SearchMethod(Value value) noexcept : m_value(value) {}  // NOLINT: implicit, as an enum's values
  /// The method named `name`, or Unknown (transitional; see the top of this file). Prefer parseSearchMethod.
  SearchMethod(std::string_view name) noexcept;  // NOLINT: implicit on purpose
  SearchMethod(const char* name) noexcept : SearchMethod(std::string_view(name)) {}         // NOLINT
  SearchMethod(const std::string& name) noexcept : SearchMethod(std::string_view(name)) {}  // NOLINT

  constexpr operator Value() const noexcept { return m_value; }  // NOLINT: switch and == as on an enum
  /// "exact", "tree", "auto" ("unknown" for Unknown).
  [[nodiscard]] std::string_view name() const noexcept;

  /// Compares the method's name with `name` (for code that still compares text).
  friend bool operator==(SearchMethod m, std::string_view name) noexcept { return m.name() == name; }
  friend bool operator==(SearchMethod m, const char* name) noexcept { return m.name() == name; }
  friend bool operator==(SearchMethod m, const std::string& name) noexcept { return m.name() == name; }
  friend bool operator==(SearchMethod a, SearchMethod b) noexcept { return a.m_value == b.m_value; }
  friend bool operator==(SearchMethod a, Value b) noexcept { return a.m_value == b; }

 private:
  Value m_value = Value::Exact;
};

/// The name of `method` in files, on the command line and in sessions: "exact", "tree", "auto" ("unknown").
std::string_view searchMethodName(SearchMethod method) noexcept;
/// The method named `name` ("exact", "tree" or "auto", exactly); std::nullopt for any other text.
std::optional<SearchMethod> parseSearchMethod(std::string_view name) noexcept;
/// Writes the method's name (test failure messages, logs).
std::ostream& operator<<(std::ostream& out, SearchMethod method);

}  // namespace st::search

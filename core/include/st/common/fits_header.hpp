#pragma once
// The cards of one FITS header, kept as text so nothing is lost between reading and writing.
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace st {

struct FitsCard {
  std::string key;      ///< upper-case keyword, e.g. "DATE-OBS"; empty for blank cards
  std::string value;    ///< value as it stands in the card; strings without their quotes
  std::string comment;  ///< comment after the '/', or the text of COMMENT/HISTORY cards
  bool isString = false;
};

class FitsHeader {
 public:
  std::vector<FitsCard> cards;

  /// The first card with this keyword (case-insensitive), or nullptr.
  [[nodiscard]] const FitsCard* find(std::string_view key) const;
  [[nodiscard]] bool has(std::string_view key) const { return find(key) != nullptr; }
  /// The card's value as text (quotes removed, trailing blanks trimmed).
  [[nodiscard]] std::optional<std::string> getString(std::string_view key) const;
  /// The card's value as a number. Numbers written as quoted strings ("0.981") are accepted, since real
  /// headers do that. Returns nullopt when absent; throws st::InputError naming the keyword when the value
  /// is present but not a number.
  [[nodiscard]] std::optional<double> getDouble(std::string_view key) const;
  /// Sets (replaces or appends) a card.
  void set(std::string key, std::string value, std::string comment = {}, bool isString = false);
  void setNumber(std::string key, double value, std::string comment = {});
  void setString(std::string key, std::string value, std::string comment = {}) {
    set(std::move(key), std::move(value), std::move(comment), true);
  }
  void erase(std::string_view key);
};

}  // namespace st

#pragma once
// A small, strict command-line parser for synthtrack-cli: --name VALUE, --name=VALUE, repeated options,
// flags and positionals. Anything unknown or malformed throws UsageError (exit code 2).
#include <map>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

namespace st::app {

class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class CliArgs {
 public:
  /// `valued` are options that take a value, `flags` take none; names without the leading "--".
  CliArgs(const std::vector<std::string>& args, std::set<std::string> valued, std::set<std::string> flags);

  [[nodiscard]] bool flag(const std::string& name) const { return m_flags.count(name) != 0; }
  [[nodiscard]] bool has(const std::string& name) const { return m_values.count(name) != 0; }
  /// The last value given for an option, or nullopt.
  [[nodiscard]] std::optional<std::string> value(const std::string& name) const;
  /// Every value given for a repeated option, in order.
  [[nodiscard]] std::vector<std::string> values(const std::string& name) const;
  /// The option as a number; throws UsageError naming the option when it is not one.
  [[nodiscard]] std::optional<double> number(const std::string& name) const;
  [[nodiscard]] std::optional<long long> integer(const std::string& name) const;
  [[nodiscard]] double number(const std::string& name, double fallback) const {
    return number(name).value_or(fallback);
  }
  [[nodiscard]] const std::vector<std::string>& positionals() const noexcept { return m_positionals; }

 private:
  std::map<std::string, std::vector<std::string>> m_values;
  std::set<std::string> m_flags;
  std::vector<std::string> m_positionals;
};

}  // namespace st::app

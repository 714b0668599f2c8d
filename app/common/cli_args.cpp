#include "cli_args.hpp"

#include <charconv>

namespace st::app {

CliArgs::CliArgs(const std::vector<std::string>& args, std::set<std::string> valued,
                 std::set<std::string> flags) {
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (a.size() > 2 && a.rfind("--", 0) == 0) {
      std::string name = a.substr(2);
      std::optional<std::string> inlineValue;
      if (const auto eq = name.find('='); eq != std::string::npos) {
        inlineValue = name.substr(eq + 1);
        name = name.substr(0, eq);
      }
      if (flags.count(name)) {
        if (inlineValue) throw UsageError("option --" + name + " takes no value");
        m_flags.insert(name);
      } else if (valued.count(name)) {
        if (inlineValue) {
          m_values[name].push_back(*inlineValue);
        } else {
          if (i + 1 >= args.size()) throw UsageError("option --" + name + " needs a value");
          m_values[name].push_back(args[++i]);
        }
      } else {
        throw UsageError("unknown option --" + name);
      }
    } else if (a == "-o") {
      if (!valued.count("o")) throw UsageError("unknown option -o");
      if (i + 1 >= args.size()) throw UsageError("option -o needs a value");
      m_values["o"].push_back(args[++i]);
    } else if (a.size() > 1 && a[0] == '-' && !(a[1] >= '0' && a[1] <= '9') && a[1] != '.') {
      throw UsageError("unknown option " + a);
    } else {
      m_positionals.push_back(a);
    }
  }
}

std::optional<std::string> CliArgs::value(const std::string& name) const {
  const auto it = m_values.find(name);
  if (it == m_values.end() || it->second.empty()) return std::nullopt;
  return it->second.back();
}

std::vector<std::string> CliArgs::values(const std::string& name) const {
  const auto it = m_values.find(name);
  return it == m_values.end() ? std::vector<std::string>{} : it->second;
}

std::optional<double> CliArgs::number(const std::string& name) const {
  const auto v = value(name);
  if (!v) return std::nullopt;
  double out = 0.0;
  const auto [ptr, ec] = std::from_chars(v->data(), v->data() + v->size(), out);
  if (ec != std::errc() || ptr != v->data() + v->size()) {
    throw UsageError("option --" + name + " needs a number, got '" + *v + "'");
  }
  return out;
}

std::optional<long long> CliArgs::integer(const std::string& name) const {
  const auto v = value(name);
  if (!v) return std::nullopt;
  long long out = 0;
  const auto [ptr, ec] = std::from_chars(v->data(), v->data() + v->size(), out);
  if (ec != std::errc() || ptr != v->data() + v->size()) {
    throw UsageError("option --" + name + " needs an integer, got '" + *v + "'");
  }
  return out;
}

}  // namespace st::app

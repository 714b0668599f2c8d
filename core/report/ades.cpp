#include "st/report/ades.hpp"

#include <algorithm>

#include "st/common/error.hpp"

namespace st::report {
namespace {

std::string trimmed(std::string_view s) {
  const auto b = s.find_first_not_of(" \t\r");
  const auto e = s.find_last_not_of(" \t\r");
  return b == std::string_view::npos ? std::string() : std::string(s.substr(b, e - b + 1));
}

void checkText(const std::string& where, const std::string& text) {
  if (text.find_first_of("|\n\r") != std::string::npos)
    throw InputError("ADES " + where + " '" + text + "' holds '|' or a line break");
}

void checkDocument(const AdesDocument& d) {
  for (const auto& b : d.context) {
    checkText("element", b.name);
    checkText(b.name, b.text);
    for (const auto& [k, v] : b.items) {
      checkText(b.name + " element", k);
      checkText(b.name + "/" + k, v);
    }
  }
  for (const auto& f : d.fields)
    checkText("field name", f);
  for (const auto& r : d.rows) {
    if (r.size() != d.fields.size()) {
      throw InputError("ADES row of " + std::to_string(r.size()) + " values for " +
                       std::to_string(d.fields.size()) + " fields");
    }
    for (std::size_t i = 0; i < r.size(); ++i)
      checkText(d.fields[i], r[i]);
  }
}

std::string xmlEscaped(const std::string& s) {
  std::string out;
  for (char c : s) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&apos;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

std::string element(const std::string& name, const std::string& text) {
  return "<" + name + ">" + xmlEscaped(text) + "</" + name + ">";
}

std::vector<std::string> splitFields(std::string_view line) {
  std::vector<std::string> out;
  std::size_t start = 0;
  for (std::size_t p; (p = line.find('|', start)) != std::string_view::npos; start = p + 1)
    out.push_back(trimmed(line.substr(start, p - start)));
  out.push_back(trimmed(line.substr(start)));
  return out;
}

[[noreturn]] void lineError(int line, const std::string& what) {
  throw InputError("ADES PSV line " + std::to_string(line) + ": " + what);
}

}  // namespace

std::string adesPsvText(const AdesDocument& d) {
  checkDocument(d);
  std::string t = "# version=" + d.version + "\n";
  for (const auto& b : d.context) {
    t += "# " + b.name + (b.text.empty() ? "" : " " + b.text) + "\n";
    for (const auto& [k, v] : b.items)
      t += "! " + k + " " + v + "\n";
  }
  std::vector<std::size_t> width(d.fields.size());
  for (std::size_t i = 0; i < d.fields.size(); ++i) {
    width[i] = d.fields[i].size();
    for (const auto& r : d.rows)
      width[i] = std::max(width[i], r[i].size());
  }
  auto emit = [&](const std::vector<std::string>& values) {
    for (std::size_t i = 0; i < values.size(); ++i) {
      std::string f = values[i];
      if (i + 1 < values.size()) f.resize(width[i], ' ');
      t += f + (i + 1 < values.size() ? "|" : "\n");
    }
  };
  emit(d.fields);
  for (const auto& r : d.rows)
    emit(r);
  return t;
}

std::string adesXmlText(const AdesDocument& d) {
  checkDocument(d);
  std::string x = "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<ades version=\"" + xmlEscaped(d.version) +
                  "\">\n  <obsBlock>\n    <obsContext>\n";
  for (const auto& b : d.context) {
    if (b.items.empty()) {
      x += "      " + element(b.name, b.text) + "\n";
      continue;
    }
    x += "      <" + b.name + ">" + xmlEscaped(b.text) + "\n";
    for (const auto& [k, v] : b.items)
      x += "        " + element(k, v) + "\n";
    x += "      </" + b.name + ">\n";
  }
  x += "    </obsContext>\n    <obsData>\n";
  for (const auto& r : d.rows) {
    x += "      <optical>\n";
    for (std::size_t i = 0; i < r.size(); ++i)
      if (!r[i].empty()) x += "        " + element(d.fields[i], r[i]) + "\n";
    x += "      </optical>\n";
  }
  x += "    </obsData>\n  </obsBlock>\n</ades>\n";
  return x;
}

AdesDocument parseAdesPsv(std::string_view psv) {
  AdesDocument d;
  bool versionSeen = false;
  int lineNo = 0;
  std::size_t pos = 0;
  while (pos < psv.size()) {
    const std::size_t end = std::min(psv.find('\n', pos), psv.size());
    const std::string line = trimmed(psv.substr(pos, end - pos));
    pos = end + 1;
    ++lineNo;
    if (line.empty()) continue;
    if (!versionSeen) {
      std::string compact;
      for (char c : line)
        if (c != ' ' && c != '\t') compact += c;
      if (compact.rfind("#version=", 0) != 0 || compact.size() == 9)
        lineError(lineNo,
                  "the first line must be '# version=" + std::string(kAdesVersion) + "', got '" + line + "'");
      d.version = compact.substr(9);
      versionSeen = true;
    } else if (line[0] == '#' || line[0] == '!') {
      if (!d.fields.empty()) lineError(lineNo, "a second obsBlock (only one is read)");
      const std::string body = trimmed(std::string_view(line).substr(1));
      const auto gap = body.find_first_of(" \t");
      std::string name = body.substr(0, gap);
      std::string value =
          gap == std::string::npos ? std::string() : trimmed(std::string_view(body).substr(gap));
      if (name.empty()) lineError(lineNo, "a header line without an element name");
      if (line[0] == '#') {
        d.context.push_back({std::move(name), std::move(value), {}});
      } else {
        if (d.context.empty()) lineError(lineNo, "a '!' line before any '#' line");
        d.context.back().items.emplace_back(std::move(name), std::move(value));
      }
    } else if (d.fields.empty()) {
      d.fields = splitFields(line);
    } else {
      auto values = splitFields(line);
      if (values.size() > d.fields.size()) {
        lineError(lineNo, std::to_string(values.size()) + " values for " + std::to_string(d.fields.size()) +
                              " field names");
      }
      values.resize(d.fields.size());
      d.rows.push_back(std::move(values));
    }
  }
  if (!versionSeen) throw InputError("ADES PSV: empty (no '# version=' line)");
  if (d.fields.empty()) throw InputError("ADES PSV: no line of field names");
  return d;
}

std::string adesXmlFromPsv(std::string_view psv) {
  return adesXmlText(parseAdesPsv(psv));
}

}  // namespace st::report

#include "st/batch/observation_list.hpp"

#include <algorithm>
#include <fstream>
#include <numeric>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include "st/common/error.hpp"

namespace st::batch {

namespace fs = std::filesystem;

namespace {

bool isFitsName(const std::string& name) {
  std::string n = name;
  std::transform(n.begin(), n.end(), n.begin(), [](unsigned char c) { return std::tolower(c); });
  for (const char* gz : {".gz", ".fz"}) {
    const std::string s = gz;
    if (n.size() > s.size() && n.compare(n.size() - s.size(), s.size(), s) == 0)
      n.resize(n.size() - s.size());
  }
  for (const char* ext : {".fits", ".fit", ".fts"}) {
    const std::string s = ext;
    if (n.size() > s.size() && n.compare(n.size() - s.size(), s.size(), s) == 0) return true;
  }
  return false;
}

/// Names unique by "-2", "-3", ... in list order.
void makeNamesUnique(std::vector<Observation>& obs) {
  std::set<std::string> used;
  for (auto& o : obs) {
    std::string n = o.name;
    for (int k = 2; used.count(n) != 0; ++k)
      n = o.name + "-" + std::to_string(k);
    o.name = n;
    used.insert(n);
  }
}

std::string nameOf(const std::string& input) {
  fs::path p(input);
  while (!p.empty() && p.filename().empty())
    p = p.parent_path();  // "night/" -> "night"
  std::string stem = p.filename().string();
  for (const char* ext : {".gz", ".fz", ".fits", ".fit", ".fts"}) {
    const std::string s = ext;
    if (stem.size() > s.size() && stem.compare(stem.size() - s.size(), s.size(), s) == 0)
      stem.resize(stem.size() - s.size());
  }
  return safeName(stem);
}

std::string relativeTo(const fs::path& base, const std::string& path) {
  const fs::path p(path);
  return p.is_absolute() ? p.string() : (base / p).lexically_normal().string();
}

std::vector<std::string> stringList(const nlohmann::json& j, const std::string& where, const fs::path& base) {
  std::vector<std::string> out;
  if (j.is_string()) {
    out.push_back(relativeTo(base, j.get<std::string>()));
  } else if (j.is_array()) {
    for (const auto& e : j) {
      if (!e.is_string()) throw InputError(where + ": expected file names (strings)");
      out.push_back(relativeTo(base, e.get<std::string>()));
    }
  } else {
    throw InputError(where + ": expected a file name or a list of them");
  }
  return out;
}

std::string optionKey(std::string key) {
  std::replace(key.begin(), key.end(), '_', '-');
  return key;
}

std::string paramText(const nlohmann::json& v, const std::string& where) {
  if (v.is_string()) return v.get<std::string>();
  if (v.is_number_integer()) return std::to_string(v.get<long long>());
  if (v.is_number()) {
    std::ostringstream s;
    s.precision(17);
    s << v.get<double>();
    return s.str();
  }
  if (v.is_boolean()) return v.get<bool>() ? "true" : "false";
  throw InputError(where + ": a search option must be a number or a string");
}

Observation observationFromJson(const nlohmann::json& e, const std::string& where, const fs::path& base) {
  if (!e.is_object()) throw InputError(where + ": expected an object");
  if (!e.contains("inputs")) throw InputError(where + ": missing key 'inputs'");
  Observation o;
  o.inputs = stringList(e["inputs"], where + " 'inputs'", base);
  if (o.inputs.empty()) throw InputError(where + ": 'inputs' is empty");
  o.name = e.contains("name") ? safeName(e["name"].get<std::string>()) : nameOf(o.inputs.front());
  if (e.contains("bias")) o.bias = stringList(e["bias"], where + " 'bias'", base);
  if (e.contains("dark")) o.dark = stringList(e["dark"], where + " 'dark'", base);
  if (e.contains("flat")) o.flat = stringList(e["flat"], where + " 'flat'", base);
  if (e.contains("group")) o.group = e["group"].get<std::string>();
  if (e.contains("params")) {
    if (!e["params"].is_object()) throw InputError(where + ": 'params' must be an object");
    for (const auto& [k, v] : e["params"].items())
      o.params[optionKey(k)] = paramText(v, where + " param '" + k + "'");
  }
  return o;
}

std::vector<std::string> splitText(const std::string& text, char sep) {
  std::vector<std::string> out;
  std::string cur;
  bool quoted = false;
  for (const char c : text) {
    if (c == '"') {
      quoted = !quoted;
    } else if (c == sep && !quoted) {
      out.push_back(cur);
      cur.clear();
    } else {
      cur += c;
    }
  }
  out.push_back(cur);
  for (auto& s : out) {
    const auto b = s.find_first_not_of(" \t\r");
    const auto e = s.find_last_not_of(" \t\r");
    s = b == std::string::npos ? std::string() : s.substr(b, e - b + 1);
  }
  return out;
}

std::vector<Observation> readCsvManifest(std::istream& in, const std::string& path, const fs::path& base) {
  std::vector<Observation> out;
  std::vector<std::string> columns;
  std::string line;
  for (int lineNo = 1; std::getline(in, line); ++lineNo) {
    const auto first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    const std::vector<std::string> fields = splitText(line, ',');
    const std::string where = path + " line " + std::to_string(lineNo);
    if (columns.empty()) {
      for (const auto& f : fields)
        columns.push_back(optionKey(f));
      if (std::find(columns.begin(), columns.end(), "inputs") == columns.end())
        throw InputError(where + ": the header names no 'inputs' column");
      continue;
    }
    if (fields.size() != columns.size()) {
      throw InputError(where + ": " + std::to_string(fields.size()) + " fields, the header has " +
                       std::to_string(columns.size()));
    }
    nlohmann::json e = nlohmann::json::object();
    for (std::size_t i = 0; i < columns.size(); ++i) {
      const std::string& c = columns[i];
      if (fields[i].empty()) continue;
      if (c == "inputs" || c == "bias" || c == "dark" || c == "flat") {
        e[c] = splitText(fields[i], ';');
      } else if (c == "name" || c == "group") {
        e[c] = fields[i];
      } else {
        e["params"][c] = fields[i];
      }
    }
    out.push_back(observationFromJson(e, where, base));
  }
  return out;
}

}  // namespace

std::string safeName(const std::string& text) {
  std::string out;
  for (const char c : text) {
    const bool ok = std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' || c == '.';
    out += ok ? c : '_';
  }
  if (out.empty() || out == "." || out == "..") out = "observation";
  return out;
}

std::vector<std::string> framesInFolder(const std::string& folder) {
  std::error_code ec;
  if (!fs::is_directory(folder, ec)) throw InputError("'" + folder + "' is not a folder");
  std::vector<std::string> files;
  for (const auto& e : fs::directory_iterator(folder, ec)) {
    if (e.is_regular_file() && isFitsName(e.path().filename().string())) files.push_back(e.path().string());
  }
  if (ec) throw InputError("cannot list '" + folder + "': " + ec.message());
  std::sort(files.begin(), files.end());
  return files;
}

std::uintmax_t inputBytes(const std::vector<std::string>& inputs) {
  std::uintmax_t total = 0;
  for (const auto& in : inputs) {
    std::error_code ec;
    if (fs::is_directory(in, ec)) {
      for (const auto& e : fs::directory_iterator(in, ec)) {
        if (e.is_regular_file()) total += e.file_size(ec);
      }
    } else {
      const auto n = fs::file_size(in, ec);
      if (!ec) total += n;
    }
  }
  return total;
}

std::vector<Observation> observationsFromInputs(const std::vector<std::string>& inputs) {
  std::vector<Observation> out;
  for (const auto& in : inputs) {
    Observation o;
    o.name = nameOf(in);
    o.inputs = {in};
    o.inputBytes = inputBytes(o.inputs);
    out.push_back(std::move(o));
  }
  makeNamesUnique(out);
  return out;
}

std::vector<Observation> readManifest(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError("cannot read the manifest '" + path + "'");
  const fs::path base = fs::absolute(path).parent_path();
  std::vector<Observation> out;
  const auto first = in.peek();
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  if (ext == ".json" || first == '[' || first == '{') {
    nlohmann::json j;
    try {
      in >> j;
    } catch (const nlohmann::json::exception& e) {
      throw InputError("manifest '" + path + "' is not valid JSON: " + e.what());
    }
    if (j.is_object() && j.contains("observations")) j = j["observations"];
    if (!j.is_array()) throw InputError("manifest '" + path + "': expected a list of observations");
    for (std::size_t i = 0; i < j.size(); ++i)
      out.push_back(observationFromJson(j[i], path + " entry " + std::to_string(i + 1), base));
  } else {
    out = readCsvManifest(in, path, base);
  }
  if (out.empty()) throw InputError("manifest '" + path + "' lists no observation");
  for (auto& o : out)
    o.inputBytes = inputBytes(o.inputs);
  makeNamesUnique(out);
  return out;
}

std::vector<std::pair<int, int>> splitRanges(int frames, int framesPerCube, int overlap) {
  if (framesPerCube < 2)
    throw InputError("--split needs at least 2 frames per cube, got " + std::to_string(framesPerCube));
  if (overlap < 0 || overlap >= framesPerCube) {
    throw InputError("--overlap must be in [0, " + std::to_string(framesPerCube - 1) + "], got " +
                     std::to_string(overlap));
  }
  std::vector<std::pair<int, int>> out;
  if (frames <= framesPerCube) {
    out.emplace_back(0, frames);
    return out;
  }
  const int stride = framesPerCube - overlap;
  for (int b = 0;; b += stride) {
    if (b + framesPerCube >= frames) {
      out.emplace_back(frames - framesPerCube, frames);
      break;
    }
    out.emplace_back(b, b + framesPerCube);
  }
  return out;
}

std::vector<Observation> splitObservation(const Observation& obs, int framesPerCube, int overlap) {
  std::vector<std::string> frames;
  for (const auto& in : obs.inputs) {
    std::error_code ec;
    if (fs::is_directory(in, ec)) {
      const auto f = framesInFolder(in);
      frames.insert(frames.end(), f.begin(), f.end());
    } else {
      frames.push_back(in);
    }
  }
  if (frames.size() == 1) {
    throw InputError("--split cuts a folder of frame files; '" + obs.inputs.front() +
                     "' is a single file (convert a cube to frames, or give it whole)");
  }
  std::vector<Observation> out;
  const auto ranges = splitRanges(static_cast<int>(frames.size()), framesPerCube, overlap);
  for (std::size_t i = 0; i < ranges.size(); ++i) {
    Observation c = obs;
    char suffix[32];
    std::snprintf(suffix, sizeof suffix, "_c%03zu", i);
    c.name = obs.name + suffix;
    c.group = obs.group.empty() ? obs.name : obs.group;
    c.inputs.assign(frames.begin() + ranges[i].first, frames.begin() + ranges[i].second);
    c.inputBytes = inputBytes(c.inputs);
    out.push_back(std::move(c));
  }
  return out;
}

std::vector<std::size_t> largestFirst(const std::vector<Observation>& observations) {
  std::vector<std::size_t> order(observations.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return observations[a].inputBytes > observations[b].inputBytes;
  });
  return order;
}

}  // namespace st::batch

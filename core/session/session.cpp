#include "st/session/session.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "st/common/error.hpp"
#include "st/report/candidate_json.hpp"

namespace st::session {
namespace {

namespace fs = std::filesystem;

std::string utcStamp() {
  const std::time_t now = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  std::tm tm{};
  gmtime_r(&now, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y%m%dT%H%M%SZ", &tm);
  return buf;
}

/// Copies the file to NAME.<tag>-<stamp>.json beside it (a numbered suffix when that exists); returns the
/// copy.
std::string backup(const std::string& path, const std::string& tag) {
  const fs::path p(path);
  const std::string stem = p.stem().string();
  const std::string base = (p.parent_path() / (stem + "." + tag + "-" + utcStamp())).string();
  std::string target = base + ".json";
  for (int i = 2; fs::exists(target); ++i)
    target = base + "-" + std::to_string(i) + ".json";
  std::error_code ec;
  fs::copy_file(path, target, ec);
  if (ec) throw InputError("session '" + path + "': could not copy it to '" + target + "': " + ec.message());
  return target;
}

void writeAll(int fd, const std::string& data, const std::string& where) {
  std::size_t done = 0;
  while (done < data.size()) {
    const ssize_t n = ::write(fd, data.data() + done, data.size() - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      throw InputError("cannot write '" + where + "': " + std::strerror(errno));
    }
    done += static_cast<std::size_t>(n);
  }
}

}  // namespace

Session fromSearchJson(const nlohmann::json& result) {
  if (!result.is_object() || !result.contains("candidates") || !result["candidates"].is_array()) {
    throw InputError("not a search result: no \"candidates\" array");
  }
  Session s;
  if (result.contains("inputs")) s.inputs = result["inputs"].get<std::vector<std::string>>();
  s.search = result;
  s.search.erase("candidates");
  std::size_t n = 0;
  for (const auto& c : result["candidates"])
    s.candidates.push_back(report::fromCandidatesFileJson(c, "candidate " + std::to_string(++n)));
  return s;
}

nlohmann::json toJson(const Session& s) {
  nlohmann::json j;
  j["format"] = kSessionFormatName;
  j["version"] = kSessionFormatVersion;
  j["changes"] = s.changes;
  j["inputs"] = s.inputs;
  j["parameters"] = s.parameters;
  j["search"] = s.search;
  j["settings"] = s.settings;
  j["notes"] = s.notes;
  j["candidates"] = nlohmann::json::array();
  for (const auto& c : s.candidates) {
    j["candidates"].push_back({{"search", report::toJson(c.search)},
                               {"fit", c.fit ? report::toNestedJson(*c.fit) : nlohmann::json(nullptr)},
                               {"artifacts", report::toJson(c.artifacts)},
                               {"label", toString(c.label)},
                               {"reason", toString(c.reason)},
                               {"note", c.note}});
  }
  return j;
}

namespace {

/// One candidate of a session file of format `version` (1: "candidate" and a flat fit; 2 and 3: "search" and
/// a nested fit).
CandidateState candidateFromJson(const nlohmann::json& c, int version, const std::string& where) {
  CandidateState cs;
  const nlohmann::json& fit = c.at("fit");
  if (version == 1) {
    cs.search = report::searchMeasurementFromJson(c.at("candidate"), where);
    if (!fit.is_null()) cs.fit = report::fitFromFlatJson(fit, where + ", fit");
  } else {
    cs.search = report::searchMeasurementFromJson(c.at("search"), where);
    if (!fit.is_null()) cs.fit = report::fitFromNestedJson(fit, where + ", fit");
  }
  cs.artifacts = report::artifactsFromJson(c.at("artifacts"), where);
  cs.label = labelFromString(c.at("label").get<std::string>());
  cs.reason = reasonFromString(c.at("reason").get<std::string>());
  cs.note = c.at("note").get<std::string>();
  return cs;
}

}  // namespace

Session fromJson(const nlohmann::json& j, const std::string& where) {
  try {
    if (!j.is_object() || j.value("format", std::string{}) != kSessionFormatName) {
      throw InputError("session '" + where + "': not a synthtrack session (no \"format\": \"" +
                       kSessionFormatName + "\")");
    }
    Session s;
    const int version = j.at("version").get<int>();
    if (version < 1 || version > kSessionFormatVersion)
      throw InputError("session '" + where + "': unknown format version " + std::to_string(version));
    s.version = version;
    s.changes = j.at("changes").get<std::int64_t>();
    s.inputs = j.at("inputs").get<std::vector<std::string>>();
    s.parameters = j.at("parameters");
    s.search = j.at("search");
    s.settings = j.at("settings");
    s.notes = j.at("notes").get<std::string>();
    std::size_t n = 0;
    for (const auto& c : j.at("candidates"))
      s.candidates.push_back(
          candidateFromJson(c, version, "session '" + where + "', candidate " + std::to_string(++n)));
    return s;
  } catch (const nlohmann::json::exception& e) {
    throw InputError("session '" + where + "': " + e.what());
  }
}

bool SessionStore::exists() const {
  return fs::exists(m_path);
}

std::string SessionStore::tempPath() const {
  return m_path + ".tmp-" + std::to_string(::getpid());
}

Session SessionStore::load() const {
  std::ifstream in(m_path, std::ios::binary);
  if (!in) throw InputError("cannot read session '" + m_path + "'");
  std::stringstream buf;
  buf << in.rdbuf();
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(buf.str());
  } catch (const nlohmann::json::exception& e) {
    const std::string copy = backup(m_path, "corrupt");
    throw InputError("session '" + m_path + "' is corrupted (" + e.what() +
                     "); it was left as it is and copied to '" + copy + "'");
  }
  if (j.is_object() && j.contains("version") && j["version"].is_number_integer() &&
      j["version"].get<long long>() > kSessionFormatVersion) {
    const std::string copy = backup(m_path, "newer");
    throw InputError("session '" + m_path + "' was written by a newer synthtrack (session format version " +
                     std::to_string(j["version"].get<long long>()) + ", this build reads up to " +
                     std::to_string(kSessionFormatVersion) + "); it was left as it is and copied to '" +
                     copy + "': open it with a newer synthtrack");
  }
  try {
    return fromJson(j, m_path);
  } catch (const InputError& e) {
    const std::string copy = backup(m_path, "corrupt");
    throw InputError(std::string(e.what()) + "; the file is corrupted: it was left as it is and copied to '" +
                     copy + "'");
  }
}

void SessionStore::save(Session& session) const {
  ++session.changes;
  const std::string text = toJson(session).dump(1) + "\n";
  const std::string tmp = tempPath();
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) {
    --session.changes;
    throw InputError("cannot write session '" + tmp + "': " + std::strerror(errno));
  }
  try {
    writeAll(fd, text, tmp);
    if (::fsync(fd) != 0) throw InputError("cannot flush session '" + tmp + "': " + std::strerror(errno));
  } catch (...) {
    ::close(fd);
    ::unlink(tmp.c_str());
    --session.changes;
    throw;
  }
  ::close(fd);
  if (::rename(tmp.c_str(), m_path.c_str()) != 0) {
    const std::string err = std::strerror(errno);
    ::unlink(tmp.c_str());
    --session.changes;
    throw InputError("cannot rename '" + tmp + "' to '" + m_path + "': " + err);
  }
  // The rename is durable once the folder's entry is on disk.
  const std::string dir =
      fs::path(m_path).parent_path().empty() ? "." : fs::path(m_path).parent_path().string();
  const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd >= 0) {
    ::fsync(dfd);
    ::close(dfd);
  }
}

CandidateState& SessionEditor::at(std::size_t i) {
  if (i >= m_session.candidates.size()) {
    throw InputError("candidate " + std::to_string(i + 1) + " does not exist (the session has " +
                     std::to_string(m_session.candidates.size()) + ", numbered from 1)");
  }
  return m_session.candidates[i];
}

void SessionEditor::setLabel(std::size_t i, Label label, ArtifactReason reason) {
  if (label != Label::Artifact && reason != ArtifactReason::None) {
    throw InputError(std::string("an artifact reason was given with the label '") + toString(label) + "'");
  }
  CandidateState& c = at(i);
  c.label = label;
  c.reason = label == Label::Artifact && reason == ArtifactReason::None ? ArtifactReason::Other : reason;
  save();
}
void SessionEditor::setNote(std::size_t i, std::string note) {
  at(i).note = std::move(note);
  save();
}
void SessionEditor::setFit(std::size_t i, std::optional<candidate::FitSummary> fit) {
  at(i).fit = std::move(fit);
  save();
}
void SessionEditor::setArtifacts(std::size_t i, std::vector<vet::ArtifactFlag> flags) {
  at(i).artifacts = std::move(flags);
  save();
}
void SessionEditor::setParameters(const std::string& stage, nlohmann::json parameters) {
  m_session.parameters[stage] = std::move(parameters);
  save();
}
void SessionEditor::setSettings(nlohmann::json settings) {
  m_session.settings = std::move(settings);
  save();
}
void SessionEditor::setSessionNotes(std::string notes) {
  m_session.notes = std::move(notes);
  save();
}

}  // namespace st::session

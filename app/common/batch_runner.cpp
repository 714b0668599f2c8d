#include "batch_runner.hpp"

#include <unistd.h>

#include <chrono>
#include <cstdio>

#include "cli_args.hpp"
#include "load_args.hpp"
#include "observation_pipeline.hpp"
#include "search_options.hpp"
#include "st/common/error.hpp"
#include "st/report/search_report.hpp"
#include "terminal_progress.hpp"

namespace st::app {

namespace fs = std::filesystem;

namespace {

/// The digest leaves out the backend: a rerun on GPU nodes of what CPU nodes did is not redone.
std::map<std::string, std::string> digestOptions(std::map<std::string, std::string> options) {
  options.erase("backend");
  return options;
}

void writeLog(const BatchSettings& s, const std::string& name, const nlohmann::json& log) {
  std::error_code ec;
  fs::create_directories(s.layout.logFile(name).parent_path(), ec);
  try {
    batch::writeJsonAtomically(s.layout.logFile(name), log);
  } catch (const InputError& e) {
    std::fprintf(stderr, "batch: warning: %s\n", e.what());
  }
}

}  // namespace

CliArgs argsForOptions(const std::map<std::string, std::string>& options) {
  std::vector<std::string> args;
  const std::set<std::string> flags = searchFlagNames();
  for (const auto& [k, v] : options) {
    args.push_back("--" + k);
    if (!flags.count(k)) args.push_back(v);
  }
  std::set<std::string> valued = searchOptionNames();
  for (const auto& n : loadOptionNames())
    valued.insert(n);
  return CliArgs(args, valued, flags);
}

std::map<std::string, std::string> effectiveOptions(const BatchSettings& settings,
                                                    const batch::Observation& obs) {
  std::map<std::string, std::string> o = settings.options;
  // A range given by the observation replaces the batch's in whatever unit.
  const bool ownRange =
      obs.params.count("vmax-px-s") + obs.params.count("vmax-arcsec-min") + obs.params.count("vmax-deg-day");
  if (ownRange) {
    for (const char* k : {"vmax-px-s", "vmax-arcsec-min", "vmax-deg-day"})
      o.erase(k);
  }
  if (obs.params.count("snr") || obs.params.count("fap")) {
    o.erase("snr");
    o.erase("fap");
  }
  for (const auto& [k, v] : obs.params)
    o[k] = v;
  return o;
}

void validateOptions(const std::map<std::string, std::string>& options) {
  const CliArgs cli = argsForOptions(options);
  (void)parseSearchOptions(cli);
  (void)loadOptionsFromArgs(cli);
}

search::SearchBackend& BackendCache::get(const std::string& backend, search::SearchMethod method,
                                         std::string& message, const std::string& framePrecision) {
  const std::string key = backend + "/" + std::string(method.name()) + "/" + framePrecision;
  auto it = m_backends.find(key);
  if (it == m_backends.end()) {
    it = m_backends
             .emplace(key, makeBackendForMethod(parseBackendChoice(backend), method,
                                                parseFramePrecision(framePrecision)))
             .first;
  }
  message = it->second.message;
  return *it->second.backend;
}

bool completedEarlier(const batch::Observation& obs, const BatchSettings& settings, batch::Outcome& outcome) {
  const std::string digest = batch::inputDigest(obs, digestOptions(effectiveOptions(settings, obs)));
  const fs::path dir = settings.layout.observationDir(obs.name);
  if (!batch::outputComplete(dir, digest)) return false;
  try {
    outcome = {obs.name,   obs.group,
               obs.inputs, batch::Outcome::Status::Done,
               {},         batch::readJsonFile(dir / batch::kResultFile)};
    return true;
  } catch (const InputError&) {
    return false;
  }
}

batch::Outcome outcomeFromDisk(const batch::Observation& obs, const BatchSettings& settings,
                               const std::string& reason) {
  batch::Outcome o;
  if (completedEarlier(obs, settings, o)) return o;
  o = {obs.name, obs.group, obs.inputs, batch::Outcome::Status::NotDone, reason, {}};
  try {
    const nlohmann::json log = batch::readJsonFile(settings.layout.logFile(obs.name));
    if (log.value("status", std::string()) == "failed") {
      o.status = batch::Outcome::Status::Failed;
      o.error = log.value("error", std::string("failed"));
    }
  } catch (const InputError&) {
  }
  return o;
}

RunOutcome runBatchObservation(const batch::Observation& obs, const BatchSettings& settings,
                               BackendCache& backends, const WorkerInfo& worker) {
  RunOutcome out;
  if (completedEarlier(obs, settings, out.outcome)) {
    out.skipped = true;
    return out;
  }
  const auto start = std::chrono::steady_clock::now();
  const auto options = effectiveOptions(settings, obs);
  const std::string digest = batch::inputDigest(obs, digestOptions(options));
  nlohmann::json log{
      {"observation", obs.name}, {"inputs", obs.inputs},          {"digest", digest},
      {"options", options},      {"rank", worker.rank},           {"pid", static_cast<long>(::getpid())},
      {"host", worker.host},     {"resources", worker.resources}, {"status", "running"}};
  writeLog(settings, obs.name, log);
  out.outcome = {obs.name, obs.group, obs.inputs, batch::Outcome::Status::Failed, {}, {}};
  try {
    const CliArgs cli = argsForOptions(options);
    const SearchOptions so = parseSearchOptions(cli);
    const ObservationInput input{obs.inputs, loadOptionsFromArgs(cli), false, obs.bias, obs.dark, obs.flat};
    std::string backendMessage;
    search::SearchBackend& backend =
        backends.get(so.backend, so.request.params.method, backendMessage, so.framePrecision);
    NullProgress progress;
    // The span of its frames, so that the catalogue can tell which observations share frames.
    double tFirst = 0.0, tLast = 0.0;
    ObservationHooks hooks;
    hooks.planned = [&](const PlannedSearch& p) {
      const auto& info = p.cube.frames.info();
      if (!info.empty()) {
        tFirst = info.front().mjdMid;
        tLast = info.back().mjdMid;
      }
    };
    nlohmann::json result = runObservation(input, so, true, backend, progress, processCancelToken(), hooks);
    result["t_first_mjd"] = tFirst;
    result["t_last_mjd"] = tLast;
    batch::StagedFolder folder(settings.layout.observationDir(obs.name));
    batch::writeJsonAtomically(folder.path() / batch::kResultFile, result);
    report::writeCandidatesCsv((folder.path() / "candidates.csv").string(), result);
    batch::writeJsonAtomically(folder.path() / batch::kDigestFile,
                               {{"digest", digest}, {"inputs", obs.inputs}, {"options", options}});
    folder.commit();
    log["backend"] = backendMessage;
    log["method"] = result.value("method", std::string());
    log["candidates"] = result["candidates"].size();
    log["status"] = "done";
    out.outcome.status = batch::Outcome::Status::Done;
    out.outcome.result = std::move(result);
  } catch (const Cancelled&) {
    throw;
  } catch (const std::exception& e) {
    out.outcome.error = e.what();
    log["status"] = "failed";
    log["error"] = e.what();
  }
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  log["seconds"] = out.seconds;
  writeLog(settings, obs.name, log);
  return out;
}

std::string notDoneLine(const std::vector<std::string>& names, std::size_t budget) {
  if (names.empty()) return "batch: every observation had finished\n";
  const std::string head = "batch: NOT DONE: ", tail = ". Rerun the same command to finish them.\n";
  // Room for the names and, when some are left out, their count.
  const std::string more = " and 18446744073709551615 more (the catalogue lists every one)";
  const std::size_t room =
      budget > head.size() + tail.size() + more.size() ? budget - head.size() - tail.size() - more.size() : 0;
  std::string list;
  std::size_t i = 0;
  for (; i < names.size(); ++i) {
    const std::string next = (list.empty() ? "" : ", ") + names[i];
    if (list.size() + next.size() > room) break;
    list += next;
  }
  if (i < names.size() && list.empty())
    list = std::to_string(names.size()) + " observations (the catalogue lists every one)";
  else if (i < names.size())
    list += " and " + std::to_string(names.size() - i) + " more (the catalogue lists every one)";
  return head + list + tail;
}

}  // namespace st::app

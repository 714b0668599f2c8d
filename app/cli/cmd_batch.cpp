// synthtrack-cli batch INPUT... --out DIR | --manifest FILE --out DIR: many observations through the same
// pipeline as `search --fit`, in one process or under mpirun (issue 17; ARCHITECTURE.md "Beyond one
// machine"). Restartable: a rerun skips what is complete and redoes the rest.
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <climits>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "batch_dispatch.hpp"
#include "cli_args.hpp"
#include "cmd_batch_track.hpp"
#include "commands.hpp"
#include "load_args.hpp"
#include "mpi_cluster.hpp"
#include "search_options.hpp"
#include "st/batch/batch_queue.hpp"
#include "st/batch/catalogue.hpp"
#include "st/common/error.hpp"

namespace st::app {
namespace {

constexpr const char* kHelp =
    "usage: synthtrack-cli batch INPUT... --out DIR [options]\n"
    "       synthtrack-cli batch --manifest FILE --out DIR [options]\n"
    "  Runs every observation (each INPUT one: a cube file or a folder of frames) through pre-processing,\n"
    "  the velocity search and the co-moving fits, as 'synthtrack-cli search --fit' does. Writes\n"
    "  DIR/observations/NAME/ (candidates.json, candidates.csv, digest.json; each folder written whole, "
    "then\n"
    "  renamed into place), DIR/logs/NAME.json (status, rank, host, seconds, error) and the merged\n"
    "  DIR/catalogue.json (candidates of all observations, the same object seen by overlapping cubes of one\n"
    "  night once; 'errors': observations that failed; 'not_done'). A rerun skips observations whose "
    "outputs\n"
    "  are complete for the same inputs (sizes, times) and options, and redoes the others.\n"
    "  Under 'mpirun -np K' rank 0 hands out observations (largest first) and merges, ranks 1..K-1 run\n"
    "  them, each on its own GPU when the node has several, else on its share of the cores.\n"
    "  --manifest FILE       JSON or CSV, one observation per entry/line: inputs, name, bias, dark, flat,\n"
    "                        group, and search options (e.g. vmax-deg-day) that override the batch's\n"
    "  --split N             cut each folder of frames into cubes of N frames ...\n"
    "  --overlap K           ... consecutive cubes sharing K frames (default N/4), so a mover is whole in "
    "one\n"
    "  --worker-timeout S    a worker silent for S seconds is declared dead (default 120)\n"
    "  --track-max-mpix M    an object seen across cubes of one night gets its full-track SNR from a fit "
    "over\n"
    "                        the cubes its track crosses, loaded together, when they hold at most M million\n"
    "                        pixels x frames (default 800; 0: never)\n"
    "  Search options (as for 'synthtrack-cli search'):\n";

std::atomic<bool> g_stop{false};
constexpr char kStoppedBySigterm[] =
    "batch: stopped by SIGTERM (mpirun ends the whole job when one rank dies)\n";
// What is not done yet, as the text a SIGTERM prints (mpirun sends it to every rank when one dies, and
// SIGKILL a second later: too soon to rely on writing files). Two buffers, the atomic index names the
// complete one, so the handler only reads finished text (async-signal-safe: write(2), errno and atomics). The
// "stopped" line and the names go out in one write(2) of at most PIPE_BUF bytes, which a pipe takes whole:
// mpirun forwarded the first of two writes and lost the second in a CI run (2026-11-28).
char g_notDoneText[2][PIPE_BUF + 1];
std::atomic<int> g_notDoneCurrent{-1};

void setNotDoneText(const std::string& text) {
  const int next = g_notDoneCurrent.load() == 0 ? 1 : 0;
  std::snprintf(g_notDoneText[next], sizeof g_notDoneText[next], "%s%s", kStoppedBySigterm, text.c_str());
  g_notDoneCurrent.store(next);
}

void onTerm(int) {
  const int savedErrno = errno;
  g_stop.store(true);
  const int cur = g_notDoneCurrent.load();
  const char* text = cur >= 0 ? g_notDoneText[cur] : kStoppedBySigterm;
  std::size_t left = std::strlen(text);
  while (left > 0) {
    const ssize_t n = ::write(2, text, left);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    text += n;
    left -= static_cast<std::size_t>(n);
  }
  errno = savedErrno;
}

std::map<std::string, std::string> batchOptions(const CliArgs& cli) {
  std::map<std::string, std::string> o;
  for (const auto& n : searchOptionNames())
    if (auto v = cli.value(n)) o[n] = *v;
  for (const auto& n : loadOptionNames())
    if (auto v = cli.value(n)) o[n] = *v;
  for (const auto& n : searchFlagNames())
    if (cli.flag(n)) o[n] = "";
  return o;
}

std::vector<batch::Observation> observationsFor(const CliArgs& cli) {
  std::vector<batch::Observation> list;
  if (cli.has("manifest")) {
    if (!cli.positionals().empty()) throw UsageError("give INPUT... or --manifest, not both");
    list = batch::readManifest(*cli.value("manifest"));
  } else {
    if (cli.positionals().empty()) throw UsageError("no INPUT given (or --manifest FILE)");
    list = batch::observationsFromInputs(cli.positionals());
  }
  if (!cli.has("split")) {
    if (cli.has("overlap")) throw UsageError("--overlap goes with --split");
    return list;
  }
  const long long n = *cli.integer("split");
  const long long k = cli.integer("overlap").value_or(n / 4);
  std::vector<batch::Observation> cut;
  for (const auto& obs : list) {
    for (auto& c : batch::splitObservation(obs, static_cast<int>(n), static_cast<int>(k)))
      cut.push_back(std::move(c));
  }
  return cut;
}

void writeSummary(const BatchSettings& settings, const std::vector<batch::Outcome>& outcomes,
                  std::size_t skipped, double seconds, int ranks) {
  nlohmann::json j{
      {"observations", outcomes.size()}, {"skipped", skipped}, {"seconds", seconds}, {"ranks", ranks}};
  std::size_t done = 0, failed = 0, notDone = 0;
  for (const auto& o : outcomes) {
    done += o.status == batch::Outcome::Status::Done;
    failed += o.status == batch::Outcome::Status::Failed;
    notDone += o.status == batch::Outcome::Status::NotDone;
  }
  j["done"] = done;
  j["failed"] = failed;
  j["not_done"] = notDone;
  batch::writeJsonAtomically(settings.layout.root / "batch.json", j);
}

}  // namespace

int cmdBatch(const Args& args) {
  std::set<std::string> valued = searchOptionNames();
  for (const auto& n : loadOptionNames())
    valued.insert(n);
  for (const char* n : {"out", "manifest", "split", "overlap", "worker-timeout", "track-max-mpix"})
    valued.insert(n);
  std::set<std::string> flags = searchFlagNames();
  flags.insert("help");
  const CliArgs cli(args, valued, flags);
  if (cli.flag("help")) {
    std::printf("%s%s%s", kHelp, searchOptionsHelp(), loadOptionsHelp());
    return 0;
  }
  if (!cli.has("out")) throw UsageError("give the output folder with --out DIR");
  BatchSettings settings{{*cli.value("out")}, batchOptions(cli)};
  const std::vector<batch::Observation> observations = observationsFor(cli);
  for (const auto& obs : observations) {
    try {
      validateOptions(effectiveOptions(settings, obs));
    } catch (const UsageError& e) {
      throw UsageError("observation " + obs.name + ": " + e.what());
    }
  }
  TrackSettings track;
  track.maxMegaVoxels = cli.number("track-max-mpix", track.maxMegaVoxels);
  if (!(track.maxMegaVoxels >= 0.0)) throw UsageError("--track-max-mpix must be 0 or more");
  DispatchSettings dispatch;
  dispatch.workerTimeoutS = cli.number("worker-timeout", dispatch.workerTimeoutS);
  if (!(dispatch.workerTimeoutS > 2.0 * dispatch.heartbeatS))
    throw UsageError("--worker-timeout must exceed " + std::to_string(2.0 * dispatch.heartbeatS) + " s");

  Cluster cluster;
  const bool root = cluster.rank() == 0;
  if (root) {
    std::filesystem::create_directories(settings.layout.root);
    std::signal(SIGTERM, onTerm);
  }
  const auto start = std::chrono::steady_clock::now();
  const std::size_t total = observations.size();
  std::size_t finished = 0, skipped = 0, failed = 0, processed = 0;
  if (root) {
    std::fprintf(stderr, "batch: %zu observations, %s\n", total,
                 cluster.active()
                     ? ("rank 0 hands out, " + std::to_string(cluster.size() - 1) + " worker ranks").c_str()
                     : "one process");
  }
  // The catalogue as it stands, rewritten as observations end (at most every 2 s), so that even a job
  // killed outright leaves one naming what is not done.
  std::vector<batch::Outcome> current;
  for (const auto& obs : observations)
    current.push_back({obs.name,
                       obs.group,
                       obs.inputs,
                       batch::Outcome::Status::NotDone,
                       "the batch ended before it ran",
                       {}});
  auto lastWrite = std::chrono::steady_clock::now();
  const auto updateState = [&](bool force) {
    std::vector<std::string> names;
    for (const auto& o : current)
      if (o.status == batch::Outcome::Status::NotDone) names.push_back(o.name);
    setNotDoneText(notDoneLine(names, PIPE_BUF - (sizeof kStoppedBySigterm - 1)));
    if (!force && current.size() > 50 &&
        std::chrono::steady_clock::now() - lastWrite < std::chrono::seconds(2))
      return;
    batch::writeJsonAtomically(settings.layout.catalogue(), batch::mergeCatalogue(current));
    lastWrite = std::chrono::steady_clock::now();
  };
  if (root) updateState(true);
  const OnOutcome onOutcome = [&](const RunOutcome& r, int rank, std::size_t index) {
    current[index] = r.outcome;
    updateState(false);
    ++finished;
    if (r.skipped) {
      ++skipped;
    } else {
      ++processed;
    }
    const bool bad = r.outcome.status == batch::Outcome::Status::Failed;
    failed += bad;
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::string what = r.skipped ? "skipped (complete)" : bad ? "FAILED: " + r.outcome.error : "done";
    if (!r.skipped) what += " in " + std::to_string(static_cast<int>(r.seconds + 0.5)) + " s";
    std::fprintf(stderr, "batch: %s %s (rank %d); %s\n", r.outcome.name.c_str(), what.c_str(), rank,
                 batch::progressLine(finished, total, skipped, failed, processed, elapsed).c_str());
  };
  std::vector<batch::Outcome> byOrder = runQueue(cluster, observations, batch::largestFirst(observations),
                                                 settings, dispatch, onOutcome, [] { return g_stop.load(); });
  if (!root) return 0;

  // Outcomes back in list order for the catalogue.
  const std::vector<std::size_t> order = batch::largestFirst(observations);
  std::vector<batch::Outcome> outcomes(observations.size());
  for (std::size_t k = 0; k < order.size(); ++k)
    outcomes[order[k]] = std::move(byOrder[k]);
  nlohmann::json catalogue = batch::mergeCatalogue(outcomes);
  addTrackSnr(catalogue, observations, outcomes, settings, track);
  batch::writeJsonAtomically(settings.layout.catalogue(), catalogue);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  writeSummary(settings, outcomes, skipped, seconds, cluster.size());
  std::printf(
      "batch: %zu observations in %.1f s (%zu skipped as complete): %zu candidates, %zu errors, %zu not "
      "done; catalogue %s\n",
      total, seconds, skipped, catalogue["candidates"].size(), catalogue["errors"].size(),
      catalogue["not_done"].size(), settings.layout.catalogue().c_str());
  for (const auto& e : catalogue["errors"])
    std::fprintf(stderr, "batch: error: %s: %s\n", e["observation"].get<std::string>().c_str(),
                 e["error"].get<std::string>().c_str());
  if (!catalogue["not_done"].empty()) {
    std::string names;
    for (const auto& e : catalogue["not_done"])
      names += (names.empty() ? "" : ", ") + e["observation"].get<std::string>();
    std::fprintf(stderr,
                 "batch: NOT DONE: %s. Their outputs are incomplete; rerun the same command to finish them "
                 "(complete observations are skipped).\n",
                 names.c_str());
    for (const auto& e : catalogue["not_done"])
      std::fprintf(stderr, "batch:   %s: %s\n", e["observation"].get<std::string>().c_str(),
                   e["reason"].get<std::string>().c_str());
    std::fflush(stderr);
    return cluster.finishRank(3);
  }
  return cluster.finishRank(catalogue["errors"].empty() ? 0 : 1);
}

}  // namespace st::app

#include "batch_dispatch.hpp"

#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <map>
#include <set>
#include <thread>

#include "st/batch/batch_queue.hpp"
#include "st/common/error.hpp"

namespace st::app {

namespace {

enum Tag : int { kReady = 1, kTask = 2, kStop = 3, kDone = 4, kHeartbeat = 5 };

using Clock = std::chrono::steady_clock;

std::vector<batch::Outcome> runLocally(const std::vector<batch::Observation>& observations,
                                       const std::vector<std::size_t>& order, const BatchSettings& settings,
                                       const OnOutcome& onOutcome,
                                       const std::function<bool()>& stopRequested) {
  BackendCache backends;
  const WorkerInfo me{0, {}, "this process"};
  std::vector<batch::Outcome> out;
  for (const std::size_t i : order) {
    const batch::Observation& obs = observations[i];
    if (stopRequested()) {
      out.push_back(
          {obs.name, obs.group, obs.inputs, batch::Outcome::Status::NotDone, "the batch was stopped", {}});
      continue;
    }
    try {
      RunOutcome r = runBatchObservation(obs, settings, backends, me);
      onOutcome(r, 0, i);
      out.push_back(std::move(r.outcome));
    } catch (const Cancelled&) {
      out.push_back({obs.name, obs.group, obs.inputs, batch::Outcome::Status::NotDone, "cancelled", {}});
    }
  }
  return out;
}

/// Rank 0: hands out work, collects outcomes, declares silent workers dead.
std::vector<batch::Outcome> dispatch(Cluster& cluster, const std::vector<batch::Observation>& observations,
                                     const std::vector<std::size_t>& order, const BatchSettings& settings,
                                     const DispatchSettings& ds, const OnOutcome& onOutcome,
                                     const std::function<bool()>& stopRequested) {
  batch::BatchQueue queue(order);
  std::map<std::size_t, batch::Outcome> outcomes;
  std::map<int, Clock::time_point> lastSeen;
  std::set<int> alive, stopped;
  for (int w = 1; w < cluster.size(); ++w) {
    alive.insert(w);
    lastSeen[w] = Clock::now();
  }
  const auto giveWork = [&](int w) {
    if (const auto i = queue.next(w)) {
      if (!cluster.send(w, kTask, std::to_string(*i))) queue.lose(w);  // noticed as dead below
    } else {
      cluster.send(w, kStop, {});
      stopped.insert(w);
    }
  };
  const auto loseWorker = [&](int w, const std::string& why) {
    alive.erase(w);
    cluster.notePeerLost(w);
    const auto held = queue.lose(w);
    std::string what = "nothing";
    if (held) {
      const batch::Observation& obs = observations[*held];
      what = obs.name;
      outcomes[*held] = outcomeFromDisk(obs, settings, "its worker, rank " + std::to_string(w) + ", " + why);
    }
    std::fprintf(stderr, "batch: rank %d %s while running %s\n", w, why.c_str(), what.c_str());
  };
  bool stop = false;
  while (!stop &&
         (queue.inFlight() > 0 || (queue.pending() > 0 && !alive.empty()) || stopped.size() < alive.size())) {
    if (stopRequested()) break;
    int src = -1, tag = 0;
    std::string bytes;
    if (cluster.receive(src, tag, bytes, 0.05)) {
      lastSeen[src] = Clock::now();
      if (alive.count(src) == 0) continue;
      if (tag == kReady) {
        giveWork(src);
      } else if (tag == kDone) {
        const auto j = nlohmann::json::parse(bytes, nullptr, false);
        const auto held = queue.heldBy(src);
        queue.finished(src);
        if (held) {
          const batch::Observation& obs = observations[*held];
          RunOutcome r;
          r.outcome =
              outcomeFromDisk(obs, settings, "its worker reported it done but its output is not there");
          if (j.is_object()) {
            r.skipped = j.value("skipped", false);
            r.seconds = j.value("seconds", 0.0);
            if (j.value("status", std::string()) == "failed") {
              r.outcome.status = batch::Outcome::Status::Failed;
              r.outcome.error = j.value("error", std::string());
            }
          }
          onOutcome(r, src, *held);
          outcomes[*held] = std::move(r.outcome);
        }
        giveWork(src);
      }
    }
    const auto now = Clock::now();
    for (const int w : std::set<int>(alive)) {
      if (stopped.count(w) != 0) continue;
      const double silent = std::chrono::duration<double>(now - lastSeen[w]).count();
      if (silent > ds.workerTimeoutS) {
        char why[96];
        std::snprintf(why, sizeof why, "stopped answering (no heartbeat for %.0f s)", silent);
        loseWorker(w, why);
      }
    }
    if (alive.empty() && queue.inFlight() == 0) stop = true;
  }
  std::vector<batch::Outcome> out;
  for (const std::size_t i : order) {
    const auto it = outcomes.find(i);
    if (it != outcomes.end()) {
      out.push_back(it->second);
      continue;
    }
    const batch::Observation& obs = observations[i];
    std::string reason =
        stopRequested() ? "the job was stopped before it finished" : "no worker was left to run it";
    if (const auto w = [&]() -> std::optional<int> {
          for (int r = 1; r < cluster.size(); ++r)
            if (queue.heldBy(r) == i) return r;
          return std::nullopt;
        }())
      reason = "it was running on rank " + std::to_string(*w) + " when the job was stopped";
    out.push_back(outcomeFromDisk(obs, settings, reason));
  }
  return out;
}

/// A worker rank: asks for work, runs it, reports, with a heartbeat thread beside it.
void work(Cluster& cluster, const std::vector<batch::Observation>& observations,
          const BatchSettings& settings, const DispatchSettings& ds) {
  const int localIndex = cluster.localRank() - (cluster.nodeHasRoot() ? 1 : 0);
  const int localWorkers = cluster.localSize() - (cluster.nodeHasRoot() ? 1 : 0);
  const WorkerInfo me{cluster.rank(), cluster.host(), chooseRankResources(localIndex, localWorkers)};
  std::atomic<bool> done{false};
  std::thread heartbeat([&] {
    while (!done.load()) {
      cluster.send(0, kHeartbeat, {});
      for (int k = 0; k < 20 && !done.load(); ++k)
        std::this_thread::sleep_for(std::chrono::duration<double>(ds.heartbeatS / 20));
    }
  });
  BackendCache backends;
  cluster.send(0, kReady, {});
  for (;;) {
    int src = -1, tag = 0;
    std::string bytes;
    if (!cluster.receive(src, tag, bytes, ds.workerTimeoutS, 0)) {
      std::fprintf(stderr, "batch: rank %d: no word from rank 0 for %.0f s; stopping\n", cluster.rank(),
                   ds.workerTimeoutS);
      break;
    }
    if (tag != kTask) break;
    const std::size_t i = std::stoul(bytes);
    nlohmann::json reply;
    try {
      const RunOutcome r = runBatchObservation(observations.at(i), settings, backends, me);
      reply = {{"status", r.outcome.status == batch::Outcome::Status::Done ? "done" : "failed"},
               {"error", r.outcome.error},
               {"skipped", r.skipped},
               {"seconds", r.seconds}};
    } catch (const std::exception& e) {
      reply = {{"status", "failed"}, {"error", e.what()}};
    }
    cluster.send(0, kDone, reply.dump());
  }
  done = true;
  heartbeat.join();
}

}  // namespace

std::vector<batch::Outcome> runQueue(Cluster& cluster, const std::vector<batch::Observation>& observations,
                                     const std::vector<std::size_t>& order, const BatchSettings& settings,
                                     const DispatchSettings& dispatchSettings, const OnOutcome& onOutcome,
                                     const std::function<bool()>& stopRequested) {
  if (!cluster.active()) return runLocally(observations, order, settings, onOutcome, stopRequested);
  if (cluster.rank() == 0)
    return dispatch(cluster, observations, order, settings, dispatchSettings, onOutcome, stopRequested);
  work(cluster, observations, settings, dispatchSettings);
  return {};
}

}  // namespace st::app

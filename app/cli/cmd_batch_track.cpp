#include "cmd_batch_track.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <set>

#include "st/candidate/candidate_fit.hpp"
#include "st/report/candidate_json.hpp"
#include "load_args.hpp"
#include "observation_pipeline.hpp"
#include "search_options.hpp"
#include "st/common/error.hpp"
#include "terminal_progress.hpp"

namespace st::app {
namespace {

constexpr double kSecondsPerDay = 86400.0;

/// Seconds (relative to the state's epoch) during which x + vx t stays in [0, size - 1]; empty when lo > hi.
void clipAxis(double p, double v, int size, double& lo, double& hi) {
  const double max = size - 1.0;
  if (std::abs(v) < 1e-12) {
    if (p < 0.0 || p > max) {
      lo = 1.0;
      hi = 0.0;
    }
    return;
  }
  const double a = (0.0 - p) / v, b = (max - p) / v;
  lo = std::max(lo, std::min(a, b));
  hi = std::min(hi, std::max(a, b));
}

nlohmann::json notMeasured(const std::string& status, const std::string& reason) {
  return {{"status", status}, {"reason", reason}};
}

}  // namespace

void addTrackSnr(nlohmann::json& catalogue, const std::vector<batch::Observation>& observations,
                 const std::vector<batch::Outcome>& outcomes, const BatchSettings& settings,
                 const TrackSettings& track) {
  std::map<std::string, std::size_t> byName;
  std::map<std::string, std::vector<std::size_t>> groups;  // Done observations with a frame span
  for (std::size_t i = 0; i < observations.size(); ++i) {
    byName[observations[i].name] = i;
    const auto& r = outcomes[i].result;
    if (!observations[i].group.empty() && outcomes[i].status == batch::Outcome::Status::Done &&
        r.contains("t_first_mjd") && r.contains("trials"))
      groups[observations[i].group].push_back(i);
  }
  for (auto& entry : catalogue["candidates"]) {
    const auto it = byName.find(entry.value("observation", std::string()));
    if (it == byName.end()) continue;
    const batch::Observation& obs = observations[it->second];
    const auto g = groups.find(obs.group);
    if (obs.group.empty() || g == groups.end() || g->second.size() < 2) continue;
    const nlohmann::json& own = outcomes[it->second].result;
    try {
      // Where the track is inside the frame, clipped to the group's frames.
      const auto state = batch::bestState(entry);
      const double tRef = entry["t_ref_mjd"].get<double>();
      const int w = own["trials"]["nx"].get<int>(), h = own["trials"]["ny"].get<int>();
      double lo = -std::numeric_limits<double>::infinity(), hi = std::numeric_limits<double>::infinity();
      clipAxis(state[0], state[2], w, lo, hi);
      clipAxis(state[1], state[3], h, lo, hi);
      std::vector<std::size_t> cubes;
      for (const std::size_t j : g->second) {
        const double a = (outcomes[j].result["t_first_mjd"].get<double>() - tRef) * kSecondsPerDay;
        const double b = (outcomes[j].result["t_last_mjd"].get<double>() - tRef) * kSecondsPerDay;
        if (lo <= hi && a <= hi && b >= lo) cubes.push_back(j);
      }
      // The observations that saw it count even when the state says otherwise (a partial detection).
      for (const auto& s : entry["seen_in"]) {
        const auto k = byName.find(s.value("observation", std::string()));
        if (k != byName.end() && std::find(cubes.begin(), cubes.end(), k->second) == cubes.end())
          cubes.push_back(k->second);
      }
      std::sort(cubes.begin(), cubes.end());
      nlohmann::json names = nlohmann::json::array();
      for (const std::size_t j : cubes)
        names.push_back(observations[j].name);
      const double ownSnr = entry.contains("fit") ? entry["fit"].value("snr", entry.value("snr", 0.0))
                                                  : entry.value("snr", 0.0);
      if (cubes.size() < 2) {
        entry["track"] = {{"status", "measured"},
                          {"snr", ownSnr},
                          {"method", "one observation holds the whole track: its own fit"},
                          {"observations", names},
                          {"frames", own.value("frames", 0)}};
        entry["track_snr"] = ownSnr;
        continue;
      }
      std::set<std::string> unique;
      for (const std::size_t j : cubes)
        unique.insert(observations[j].inputs.begin(), observations[j].inputs.end());
      const std::vector<std::string> inputs(unique.begin(), unique.end());
      const double megaVoxels = static_cast<double>(inputs.size()) * w * h / 1e6;
      if (megaVoxels > track.maxMegaVoxels) {
        entry["track"] =
            notMeasured("not measured", std::to_string(inputs.size()) + " frames of " + std::to_string(w) +
                                            "x" + std::to_string(h) + " px exceed the limit of " +
                                            std::to_string(static_cast<long long>(track.maxMegaVoxels)) +
                                            " million pixels x frames");
        entry["track"]["observations"] = names;
        entry["track_snr"] = nullptr;
        continue;
      }
      const CliArgs cli = argsForOptions(effectiveOptions(settings, obs));
      const SearchOptions so = parseSearchOptions(cli);
      const ObservationInput in{inputs, loadOptionsFromArgs(cli), false, obs.bias, obs.dark, obs.flat};
      NullProgress progress;
      std::vector<std::string> warnings;
      const pipeline::Prepared prepared =
          prepareObservation(in, so, progress, processCancelToken(), warnings);
      const double tRefU = prepared.frames.tRefMjd();
      const double dt = (tRefU - tRef) * kSecondsPerDay;
      search::Candidate c;
      c.x = static_cast<int>(std::lround(state[0] + state[2] * dt));
      c.y = static_cast<int>(std::lround(state[1] + state[3] * dt));
      c.v = {state[2], state[3]};
      c.snr = entry.value("snr", 0.0);
      c.nIn = static_cast<int>(prepared.frames.frameCount());
      nlohmann::json fit = report::toFlatJson(candidate::fitCandidate(prepared, c, processCancelToken()));
      entry["track"] = {{"status", fit.value("status", std::string())},
                        {"snr", fit.value("snr", 0.0)},
                        {"method", "co-moving fit over the union of the observations its track crosses"},
                        {"observations", names},
                        {"frames", prepared.frames.frameCount()},
                        {"t_ref_mjd", tRefU},
                        {"fit", fit}};
      entry["track_snr"] = fit.value("snr", 0.0);
      std::fprintf(stderr,
                   "batch: track of %s (%.1f, %.1f) over %zu frames of %zu observations: SNR %.1f (%s)\n",
                   obs.name.c_str(), state[0], state[1], prepared.frames.frameCount(), cubes.size(),
                   fit.value("snr", 0.0), fit.value("status", std::string()).c_str());
    } catch (const Cancelled&) {
      throw;
    } catch (const std::exception& e) {
      entry["track"] = notMeasured("failed", e.what());
      entry["track_snr"] = nullptr;
    }
  }
}

}  // namespace st::app

#include "st/batch/catalogue.hpp"

#include <algorithm>
#include <cmath>
#include <map>

namespace st::batch {

namespace {

constexpr double kSecondsPerDay = 86400.0;

/// One detection on its way into the catalogue.
struct Detection {
  std::size_t outcome = 0;  ///< index into the outcomes (list order)
  const nlohmann::json* candidate = nullptr;
  double tRefMjd = 0.0;
  double stepPxS = 0.0;
  std::array<double, 4> state{};  ///< x, y, vx, vy
  double snr = 0.0;
};

bool sameObject(const Detection& a, const Detection& b, const MatchParams& m) {
  const double step = std::max(a.stepPxS, b.stepPxS);
  if (std::abs(a.state[2] - b.state[2]) > m.velocityTolSteps * step) return false;
  if (std::abs(a.state[3] - b.state[3]) > m.velocityTolSteps * step) return false;
  // b moved to a's epoch with its own velocity.
  const double dt = (a.tRefMjd - b.tRefMjd) * kSecondsPerDay;
  const double bx = b.state[0] + b.state[2] * dt;
  const double by = b.state[1] + b.state[3] * dt;
  const double tol = m.positionTolPx + step * std::abs(dt);
  return std::hypot(a.state[0] - bx, a.state[1] - by) <= tol;
}

nlohmann::json entryFor(const Detection& d, const std::string& observation) {
  const nlohmann::json& c = *d.candidate;
  nlohmann::json e;
  e["observation"] = observation;
  e["t_ref_mjd"] = d.tRefMjd;
  for (const char* k :
       {"x", "y", "vx_px_s", "vy_px_s", "snr", "n_frames", "fap", "flags", "rate_deg_day", "pa_deg", "fit"}) {
    if (c.contains(k)) e[k] = c[k];
  }
  return e;
}

}  // namespace

std::array<double, 4> bestState(const nlohmann::json& c) {
  if (c.contains("fit") && c["fit"].value("status", std::string()) == "converged") {
    const auto& f = c["fit"];
    return {f["x"].get<double>(), f["y"].get<double>(), f["vx_px_s"].get<double>(),
            f["vy_px_s"].get<double>()};
  }
  return {c["x"].get<double>(), c["y"].get<double>(), c["vx_px_s"].get<double>(), c["vy_px_s"].get<double>()};
}

nlohmann::json mergeCatalogue(const std::vector<Outcome>& outcomes, const MatchParams& match) {
  nlohmann::json cat;
  cat["observations"] = nlohmann::json::array();
  cat["candidates"] = nlohmann::json::array();
  cat["errors"] = nlohmann::json::array();
  cat["not_done"] = nlohmann::json::array();
  // Detections by group; an empty group is the observation's own.
  std::map<std::string, std::vector<Detection>> groups;
  std::vector<std::string> groupOrder;
  for (std::size_t i = 0; i < outcomes.size(); ++i) {
    const Outcome& o = outcomes[i];
    cat["observations"].push_back(o.name);
    if (o.status == Outcome::Status::Failed) {
      cat["errors"].push_back({{"observation", o.name}, {"inputs", o.inputs}, {"error", o.error}});
      continue;
    }
    if (o.status == Outcome::Status::NotDone) {
      cat["not_done"].push_back({{"observation", o.name}, {"reason", o.error}});
      continue;
    }
    const std::string key = o.group.empty() ? "\x01" + o.name : o.group;
    if (groups.find(key) == groups.end()) groupOrder.push_back(key);
    auto& list = groups[key];
    const double tRef = o.result.value("t_ref_mjd", 0.0);
    const double step = o.result.contains("grid") ? o.result["grid"].value("step_px_s", 0.0) : 0.0;
    if (!o.result.contains("candidates")) continue;
    for (const auto& c : o.result["candidates"])
      list.push_back({i, &c, tRef, step, bestState(c), c.value("snr", 0.0)});
  }
  // Within a group, brightest first: each detection joins the first brighter entry it matches.
  std::vector<std::pair<Detection, nlohmann::json>> entries;
  for (const auto& key : groupOrder) {
    auto& list = groups[key];
    std::stable_sort(list.begin(), list.end(), [](const Detection& a, const Detection& b) {
      if (a.snr != b.snr) return a.snr > b.snr;
      return a.outcome < b.outcome;
    });
    const std::size_t first = entries.size();
    for (const Detection& d : list) {
      bool merged = false;
      for (std::size_t e = first; e < entries.size() && !merged; ++e) {
        if (entries[e].first.outcome == d.outcome || !sameObject(entries[e].first, d, match)) continue;
        entries[e].second["seen_in"].push_back({{"observation", outcomes[d.outcome].name},
                                                {"x", (*d.candidate)["x"]},
                                                {"y", (*d.candidate)["y"]},
                                                {"snr", d.snr}});
        merged = true;
      }
      if (merged) continue;
      nlohmann::json e = entryFor(d, outcomes[d.outcome].name);
      e["seen_in"] = nlohmann::json::array();
      e["seen_in"].push_back({{"observation", outcomes[d.outcome].name},
                              {"x", (*d.candidate)["x"]},
                              {"y", (*d.candidate)["y"]},
                              {"snr", d.snr}});
      entries.emplace_back(d, std::move(e));
    }
  }
  std::stable_sort(entries.begin(), entries.end(), [](const auto& a, const auto& b) {
    if (a.first.outcome != b.first.outcome) return a.first.outcome < b.first.outcome;
    return a.first.snr > b.first.snr;
  });
  for (auto& e : entries)
    cat["candidates"].push_back(std::move(e.second));
  return cat;
}

}  // namespace st::batch

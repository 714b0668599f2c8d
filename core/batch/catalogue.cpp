#include "st/batch/catalogue.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <optional>
#include <set>

#include "st/report/candidate_json.hpp"

namespace st::batch {

namespace {

constexpr double kSecondsPerDay = 86400.0;
constexpr double kUnknown = std::numeric_limits<double>::quiet_NaN();

/// One detection on its way into the catalogue.
struct Detection {
  std::size_t outcome = 0;  ///< index into the outcomes (list order)
  const nlohmann::json* candidate = nullptr;
  double tRefMjd = 0.0;
  double stepPxS = 0.0;
  std::array<double, 4> state{};  ///< x, y, vx, vy
  double snr = 0.0;
  double tFirstMjd = kUnknown;  ///< mid-times of the observation's first and last frames (when known)
  double tLastMjd = kUnknown;
};

/// Where `d`'s track is at `mjd`.
std::array<double, 2> positionAt(const Detection& d, double mjd) {
  const double dt = (mjd - d.tRefMjd) * kSecondsPerDay;
  return {d.state[0] + d.state[2] * dt, d.state[1] + d.state[3] * dt};
}

/// Two detections from observations that share frames (overlapping cubes of one night): the same object
/// when their tracks stay within `overlapTolPx` of each other at the start, middle and end of the shared
/// frames. Both saw the object there, so their positions agree even when one track is a partial detection
/// at a cube's edge whose velocity is off; two different objects would have to coincide throughout.
/// nullopt when the spans are unknown or do not overlap.
std::optional<bool> sameInSharedFrames(const Detection& a, const Detection& b, const MatchParams& m) {
  if (std::isnan(a.tFirstMjd) || std::isnan(b.tFirstMjd)) return std::nullopt;
  const double t0 = std::max(a.tFirstMjd, b.tFirstMjd);
  const double t1 = std::min(a.tLastMjd, b.tLastMjd);
  if (!(t1 >= t0)) return std::nullopt;
  for (const double t : {t0, 0.5 * (t0 + t1), t1}) {
    const auto pa = positionAt(a, t);
    const auto pb = positionAt(b, t);
    if (std::hypot(pa[0] - pb[0], pa[1] - pb[1]) > m.overlapTolPx) return false;
  }
  return true;
}

bool sameObject(const Detection& a, const Detection& b, const MatchParams& m) {
  if (const auto shared = sameInSharedFrames(a, b, m)) return *shared;
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
  if (c.contains("fit")) {  // the typed record decides what "converged" means (candidate::FitSummary)
    const candidate::FitSummary fit = report::fitFromFlatJson(c["fit"], "catalogue: candidate's fit");
    if (fit.converged()) return {fit.x, fit.y, fit.v.vx, fit.v.vy};
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
    const double tFirst = o.result.value("t_first_mjd", kUnknown);
    const double tLast = o.result.value("t_last_mjd", kUnknown);
    for (const auto& c : o.result["candidates"])
      list.push_back({i, &c, tRef, step, bestState(c), c.value("snr", 0.0), tFirst, tLast});
  }
  // Within a group: single-linkage clusters of matching detections (a mover crossing several cubes is
  // matched cube to cube along its track), never two detections of one observation in one cluster. Pairs
  // are linked brightest first; each cluster is one entry quoting its brightest detection.
  std::vector<std::pair<Detection, nlohmann::json>> entries;
  for (const auto& key : groupOrder) {
    auto& list = groups[key];
    std::stable_sort(list.begin(), list.end(), [](const Detection& a, const Detection& b) {
      if (a.snr != b.snr) return a.snr > b.snr;
      return a.outcome < b.outcome;
    });
    std::vector<std::size_t> root(list.size());
    std::vector<std::set<std::size_t>> seen(list.size());  // a cluster's observations, at its root
    for (std::size_t i = 0; i < list.size(); ++i) {
      root[i] = i;
      seen[i].insert(list[i].outcome);
    }
    const auto find = [&](std::size_t i) {
      while (root[i] != i)
        i = root[i] = root[root[i]];
      return i;
    };
    for (std::size_t i = 0; i < list.size(); ++i) {
      for (std::size_t j = i + 1; j < list.size(); ++j) {
        std::size_t ri = find(i), rj = find(j);
        if (ri == rj || list[i].outcome == list[j].outcome || !sameObject(list[i], list[j], match)) continue;
        if (rj < ri) std::swap(ri, rj);  // the brighter root stays
        bool disjoint = true;
        for (const std::size_t o : seen[rj])
          disjoint = disjoint && seen[ri].count(o) == 0;
        if (!disjoint) continue;
        root[rj] = ri;
        seen[ri].insert(seen[rj].begin(), seen[rj].end());
        seen[rj].clear();
      }
    }
    std::map<std::size_t, std::size_t> entryOf;  // root -> index in entries
    for (std::size_t i = 0; i < list.size(); ++i) {
      const Detection& d = list[i];
      const std::size_t r = find(i);
      if (r == i) {
        nlohmann::json e = entryFor(d, outcomes[d.outcome].name);
        e["seen_in"] = nlohmann::json::array();
        entryOf[i] = entries.size();
        entries.emplace_back(d, std::move(e));
      }
      entries[entryOf.at(r)].second["seen_in"].push_back({{"observation", outcomes[d.outcome].name},
                                                          {"x", (*d.candidate)["x"]},
                                                          {"y", (*d.candidate)["y"]},
                                                          {"snr", d.snr}});
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

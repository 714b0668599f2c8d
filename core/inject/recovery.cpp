#include "st/inject/recovery.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>

#include "st/common/error.hpp"
#include "st/common/units.hpp"
#include "st/inject/completeness_svg.hpp"
#include "st/report/search_report.hpp"

namespace st::inject {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

double number(const nlohmann::json& j, const char* key, const std::string& where) {
  if (!j.is_object() || !j.contains(key)) throw InputError(where + ": missing key '" + key + "'");
  if (!j[key].is_number()) throw InputError(where + ": key '" + key + "' is not a number");
  return j[key].get<double>();
}

std::string edgeText(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

std::string magnitudeText(const std::optional<double>& m) { return m ? edgeText(*m) : std::string(); }

void openCsv(std::ofstream& out, const std::filesystem::path& path) {
  out.open(path);
  if (!out) throw InputError("cannot write '" + path.string() + "'");
  out.precision(10);
}

nlohmann::json binsToJson(const std::vector<CompletenessBin>& bins) {
  nlohmann::json a = nlohmann::json::array();
  for (const auto& b : bins)
    a.push_back({{"label", b.label},
                 {"lo", std::isfinite(b.lo) ? nlohmann::json(b.lo) : nlohmann::json(nullptr)},
                 {"hi", std::isfinite(b.hi) ? nlohmann::json(b.hi) : nlohmann::json(nullptr)},
                 {"total", b.total},
                 {"recovered", b.recovered},
                 {"completeness", b.fraction},
                 {"err_low", b.errLow},
                 {"err_high", b.errHigh},
                 {"mean_value", b.valueMean}});
  return a;
}

}  // namespace

namespace {

/// Totals, bins and the median SNR ratio from r.objects.
void summarise(RecoveryResult& r, const RecoveryParams& params) {
  std::vector<double> snrs, ratios, mags;
  std::vector<bool> found;
  bool allMags = !r.objects.empty();
  r.recovered = 0;
  r.setAsideStatic = 0;
  for (const auto& o : r.objects) {
    r.setAsideStatic += o.setAsideStatic() ? 1 : 0;
    if (o.recovered()) {
      ratios.push_back(o.snrRatio);
      ++r.recovered;
    }
    snrs.push_back(o.truth.expectedSnr);
    found.push_back(o.recovered());
    if (o.truth.magnitude) mags.push_back(*o.truth.magnitude);
    allMags = allMags && o.truth.magnitude.has_value();
  }
  r.total = static_cast<int>(r.objects.size());
  r.medianSnrRatio.reset();
  if (!ratios.empty()) r.medianSnrRatio = median(ratios);
  r.snrBins = completenessBins(snrs, found, params.snrEdges);
  r.magBins.clear();
  if (allMags && params.magBinWidth > 0.0) {
    const double w = params.magBinWidth;
    const double lo = std::floor(*std::min_element(mags.begin(), mags.end()) / w) * w;
    const double hi = std::floor(*std::max_element(mags.begin(), mags.end()) / w) * w;
    std::vector<double> edges;
    for (double e = lo; e <= hi + 0.5 * w; e += w)
      edges.push_back(e);
    r.magBins = completenessBins(mags, found, edges);
  }
}

}  // namespace

CandidateSet candidatesFromJson(const nlohmann::json& j) {
  CandidateSet set;
  const nlohmann::json* list = &j;
  if (j.is_object()) {
    if (!j.contains("candidates") || !j["candidates"].is_array())
      throw InputError("candidates: no 'candidates' array (give the JSON of 'synthtrack-cli search --json')");
    list = &j["candidates"];
    if (j.contains("t_ref_mjd") && j["t_ref_mjd"].is_number()) set.tRefMjd = j["t_ref_mjd"].get<double>();
    if (j.contains("grid") && j["grid"].is_object() && j["grid"].contains("step_px_s"))
      set.gridStepPxS = number(j["grid"], "step_px_s", "candidates: grid");
  } else if (!j.is_array()) {
    throw InputError("candidates: neither a search result object nor an array of candidates");
  }
  auto records = [](const nlohmann::json& arr, const std::string& what) {
    std::vector<CandidateRecord> out;
    for (std::size_t k = 0; k < arr.size(); ++k) {
      const auto& c = arr[k];
      const std::string where = what + " " + std::to_string(k);
      CandidateRecord r;
      r.index = static_cast<int>(k);
      r.xPx = number(c, "x", where);
      r.yPx = number(c, "y", where);
      r.vxPxS = number(c, "vx_px_s", where);
      r.vyPxS = number(c, "vy_px_s", where);
      r.snr = number(c, "snr", where);
      if (c.contains("flags") && c["flags"].is_array())
        for (const auto& f : c["flags"])
          if (f.is_string()) r.flags.push_back(f.get<std::string>());
      out.push_back(r);
    }
    return out;
  };
  set.candidates = records(*list, "candidate");
  if (j.is_object() && j.contains("static_sources")) {
    if (!j["static_sources"].is_array()) throw InputError("candidates: 'static_sources' is not an array");
    set.staticSources = records(j["static_sources"], "static source");
  }
  return set;
}

std::pair<double, double> wilsonInterval(int k, int n, double z) {
  if (n <= 0) return {0.0, 1.0};
  const double nn = n, p = k / nn, z2 = z * z;
  const double centre = (p + z2 / (2 * nn)) / (1 + z2 / nn);
  const double half = z / (1 + z2 / nn) * std::sqrt(p * (1 - p) / nn + z2 / (4 * nn * nn));
  // The bounds are exactly 0 at k = 0 and 1 at k = n; rounding would leave 1e-18 there.
  return {k == 0 ? 0.0 : std::max(0.0, centre - half), k == n ? 1.0 : std::min(1.0, centre + half)};
}

std::vector<CompletenessBin> completenessBins(const std::vector<double>& values, const std::vector<bool>& recovered,
                                              const std::vector<double>& edges) {
  if (values.size() != recovered.size()) throw InputError("completeness bins: sizes differ");
  if (edges.empty()) throw InputError("completeness bins: no bin edges");
  for (std::size_t i = 1; i < edges.size(); ++i)
    if (!(edges[i] > edges[i - 1]))
      throw InputError("completeness bins: edges must increase, got " + edgeText(edges[i - 1]) + " then " +
                       edgeText(edges[i]));
  std::vector<CompletenessBin> bins;
  const bool below = std::any_of(values.begin(), values.end(), [&](double v) { return v < edges.front(); });
  if (below) bins.push_back({-kInf, edges.front(), "<" + edgeText(edges.front())});
  for (std::size_t i = 0; i + 1 < edges.size(); ++i)
    bins.push_back({edges[i], edges[i + 1], edgeText(edges[i]) + "-" + edgeText(edges[i + 1])});
  bins.push_back({edges.back(), kInf, ">=" + edgeText(edges.back())});
  for (auto& b : bins) {
    double sum = 0.0;
    b.valueMin = kInf;
    b.valueMax = -kInf;
    for (std::size_t i = 0; i < values.size(); ++i) {
      if (!(values[i] >= b.lo && values[i] < b.hi)) continue;
      ++b.total;
      b.recovered += recovered[i] ? 1 : 0;
      sum += values[i];
      b.valueMin = std::min(b.valueMin, values[i]);
      b.valueMax = std::max(b.valueMax, values[i]);
    }
    b.fraction = b.total > 0 ? static_cast<double>(b.recovered) / b.total : 0.0;
    std::tie(b.errLow, b.errHigh) = wilsonInterval(b.recovered, b.total);
    b.valueMean = b.total > 0 ? sum / b.total : 0.0;
    if (b.total == 0) b.valueMin = b.valueMax = 0.0;
  }
  return bins;
}

RecoveryResult matchRecovery(const Truth& truth, const CandidateSet& cands, const RecoveryParams& params) {
  if (!(params.matchPx > 0.0)) throw InputError("recovery: --match-px must be > 0, got " + edgeText(params.matchPx));
  RecoveryResult r;
  r.matchPx = params.matchPx;
  if (params.matchVPxS) {
    r.matchVPxS = *params.matchVPxS;
  } else if (cands.gridStepPxS) {
    r.matchVPxS = params.matchVSteps * *cands.gridStepPxS;
  } else {
    throw InputError("recovery: the candidates carry no grid step (grid.step_px_s); give a velocity tolerance");
  }
  if (!(r.matchVPxS > 0.0)) throw InputError("recovery: the velocity tolerance must be > 0");
  if (truth.tRefMjd && cands.tRefMjd) r.timeShiftS = (*truth.tRefMjd - *cands.tRefMjd) * kSecondsPerDay;
  const auto& cs = cands.candidates;
  auto posAtTruth = [&](const CandidateRecord& c) {
    return std::pair{c.xPx + c.vxPxS * r.timeShiftS, c.yPx + c.vyPxS * r.timeShiftS};
  };
  struct Pair {
    std::size_t t, c;
    double d;
  };
  // The position error when `c` qualifies for object `o`, else +inf.
  auto matchError = [&](const TruthObject& o, const CandidateRecord& c) {
    const auto [x, y] = posAtTruth(c);
    const double d = std::hypot(x - o.xPx, y - o.yPx);
    const bool ok = d <= r.matchPx && std::abs(c.vxPxS - o.vxPxS) <= r.matchVPxS &&
                    std::abs(c.vyPxS - o.vyPxS) <= r.matchVPxS;
    return ok ? d : kInf;
  };
  std::vector<Pair> pairs;
  for (std::size_t t = 0; t < truth.objects.size(); ++t)
    for (std::size_t c = 0; c < cs.size(); ++c)
      if (const double d = matchError(truth.objects[t], cs[c]); std::isfinite(d)) pairs.push_back({t, c, d});
  std::sort(pairs.begin(), pairs.end(), [&](const Pair& a, const Pair& b) {
    return a.d != b.d ? a.d < b.d : cs[a.c].snr > cs[b.c].snr;
  });
  std::vector<int> candOf(truth.objects.size(), -1), truthOf(cs.size(), -1);
  std::vector<bool> qualified(cs.size(), false);
  for (const auto& p : pairs) {
    qualified[p.c] = true;
    if (candOf[p.t] >= 0 || truthOf[p.c] >= 0) continue;
    candOf[p.t] = static_cast<int>(p.c);
    truthOf[p.c] = static_cast<int>(p.t);
  }
  for (std::size_t t = 0; t < truth.objects.size(); ++t) {
    ObjectOutcome o;
    o.truth = truth.objects[t];
    o.candidate = candOf[t];
    if (o.recovered()) {
      const auto& c = cs[static_cast<std::size_t>(o.candidate)];
      const auto [x, y] = posAtTruth(c);
      o.positionErrorPx = std::hypot(x - o.truth.xPx, y - o.truth.yPx);
      o.vxErrorPxS = c.vxPxS - o.truth.vxPxS;
      o.vyErrorPxS = c.vyPxS - o.truth.vyPxS;
      o.recoveredSnr = c.snr;
      o.snrRatio = o.truth.expectedSnr > 0.0 ? c.snr / o.truth.expectedSnr : 0.0;
    } else {
      double best = kInf;
      for (std::size_t k = 0; k < cands.staticSources.size(); ++k)
        if (const double d = matchError(o.truth, cands.staticSources[k]); d < best) {
          best = d;
          o.staticSource = static_cast<int>(k);
          o.staticSnr = cands.staticSources[k].snr;
        }
    }
    r.objects.push_back(o);
  }
  for (std::size_t c = 0; c < cs.size(); ++c) {
    if (truthOf[c] >= 0) continue;
    UnmatchedCandidate u;
    u.candidate = cs[c];
    u.duplicate = qualified[c];
    double best = kInf;
    const auto [x, y] = posAtTruth(cs[c]);
    for (const auto& o : truth.objects)
      if (const double d = std::hypot(x - o.xPx, y - o.yPx); d < best) {
        best = d;
        u.nearestId = o.id;
      }
    u.nearestDistancePx = std::isfinite(best) ? best : 0.0;
    r.unmatched.push_back(u);
  }
  summarise(r, params);
  return r;
}

RecoveryResult combineRecovery(const std::vector<RecoveryResult>& parts, const RecoveryParams& params) {
  RecoveryResult r;
  if (parts.empty()) return r;
  r.matchPx = parts.front().matchPx;
  r.matchVPxS = parts.front().matchVPxS;
  for (std::size_t k = 0; k < parts.size(); ++k) {
    for (auto o : parts[k].objects) {
      o.set = static_cast<int>(k);
      r.objects.push_back(o);
    }
    for (auto u : parts[k].unmatched) {
      u.set = static_cast<int>(k);
      r.unmatched.push_back(u);
    }
  }
  summarise(r, params);
  return r;
}

nlohmann::json recoveryToJson(const RecoveryResult& r) {
  nlohmann::json j;
  j["summary"] = {{"injected", r.total},
                  {"recovered", r.recovered},
                  {"completeness", r.total > 0 ? static_cast<double>(r.recovered) / r.total : 0.0},
                  {"set_aside_static", r.setAsideStatic},
                  {"unmatched_candidates", r.unmatched.size()},
                  {"median_snr_ratio", r.medianSnrRatio ? nlohmann::json(*r.medianSnrRatio) : nlohmann::json(nullptr)},
                  {"match_px", r.matchPx},
                  {"match_v_px_s", r.matchVPxS},
                  {"time_shift_s", r.timeShiftS}};
  j["snr_bins"] = binsToJson(r.snrBins);
  j["magnitude_bins"] = binsToJson(r.magBins);
  j["error_bars"] = "Wilson score interval, 1 sigma (68.3%)";
  j["objects"] = nlohmann::json::array();
  for (const auto& o : r.objects) {
    nlohmann::json e = {{"set", o.set},
                        {"id", o.truth.id},
                        {"x_px", o.truth.xPx},
                        {"y_px", o.truth.yPx},
                        {"vx_px_s", o.truth.vxPxS},
                        {"vy_px_s", o.truth.vyPxS},
                        {"expected_snr", o.truth.expectedSnr},
                        {"magnitude", o.truth.magnitude ? nlohmann::json(*o.truth.magnitude) : nlohmann::json(nullptr)},
                        {"recovered", o.recovered()}};
    if (o.recovered()) {
      e["candidate"] = o.candidate;
      e["recovered_snr"] = o.recoveredSnr;
      e["snr_ratio"] = o.snrRatio;
      e["position_error_px"] = o.positionErrorPx;
      e["vx_error_px_s"] = o.vxErrorPxS;
      e["vy_error_px_s"] = o.vyErrorPxS;
    }
    if (o.setAsideStatic()) {
      e["static_source"] = o.staticSource;
      e["static_snr"] = o.staticSnr;
    }
    j["objects"].push_back(e);
  }
  j["unmatched"] = nlohmann::json::array();
  for (const auto& u : r.unmatched)
    j["unmatched"].push_back({{"set", u.set},
                              {"candidate", u.candidate.index},
                              {"x", u.candidate.xPx},
                              {"y", u.candidate.yPx},
                              {"vx_px_s", u.candidate.vxPxS},
                              {"vy_px_s", u.candidate.vyPxS},
                              {"snr", u.candidate.snr},
                              {"flags", u.candidate.flags},
                              {"duplicate", u.duplicate},
                              {"nearest_id", u.nearestId},
                              {"nearest_distance_px", u.nearestDistancePx}});
  return j;
}

void writeRecoveryCsv(const RecoveryResult& r, const std::string& dir) {
  const std::filesystem::path d(dir);
  std::error_code ec;
  std::filesystem::create_directories(d, ec);
  if (ec) throw InputError("cannot create the folder '" + d.string() + "': " + ec.message());
  {
    std::ofstream out;
    openCsv(out, d / "completeness.csv");
    out << "kind,label,lo,hi,total,recovered,completeness,err_low,err_high,mean_value\n";
    auto rows = [&](const char* kind, const std::vector<CompletenessBin>& bins) {
      for (const auto& b : bins) {
        out << kind << ',' << b.label << ',';
        if (std::isfinite(b.lo)) out << b.lo;
        out << ',';
        if (std::isfinite(b.hi)) out << b.hi;
        out << ',' << b.total << ',' << b.recovered << ',' << b.fraction << ',' << b.errLow << ',' << b.errHigh
            << ',' << b.valueMean << '\n';
      }
    };
    rows("snr", r.snrBins);
    rows("magnitude", r.magBins);
    if (!out) throw InputError("error writing '" + (d / "completeness.csv").string() + "'");
  }
  {
    std::ofstream out;
    openCsv(out, d / "objects.csv");
    out << "set,id,x_px,y_px,vx_px_s,vy_px_s,expected_snr,magnitude,recovered,candidate,recovered_snr,snr_ratio,"
           "position_error_px,static_source\n";
    for (const auto& o : r.objects) {
      out << o.set << ',' << o.truth.id << ',' << o.truth.xPx << ',' << o.truth.yPx << ',' << o.truth.vxPxS << ','
          << o.truth.vyPxS << ',' << o.truth.expectedSnr << ',' << magnitudeText(o.truth.magnitude) << ','
          << (o.recovered() ? 1 : 0) << ',';
      if (o.recovered())
        out << o.candidate << ',' << o.recoveredSnr << ',' << o.snrRatio << ',' << o.positionErrorPx;
      else
        out << ",,,";
      out << ',';
      if (o.setAsideStatic()) out << o.staticSource;
      out << '\n';
    }
    if (!out) throw InputError("error writing '" + (d / "objects.csv").string() + "'");
  }
  {
    std::ofstream out;
    openCsv(out, d / "unmatched.csv");
    out << "set,candidate,x,y,vx_px_s,vy_px_s,snr,flags,duplicate,nearest_id,nearest_distance_px\n";
    for (const auto& u : r.unmatched) {
      std::string flags;
      for (const auto& f : u.candidate.flags)
        flags += (flags.empty() ? "" : " ") + f;
      out << u.set << ',' << u.candidate.index << ',' << u.candidate.xPx << ',' << u.candidate.yPx << ',' << u.candidate.vxPxS
          << ',' << u.candidate.vyPxS << ',' << u.candidate.snr << ',' << flags << ',' << (u.duplicate ? 1 : 0)
          << ',' << u.nearestId << ',' << u.nearestDistancePx << '\n';
    }
    if (!out) throw InputError("error writing '" + (d / "unmatched.csv").string() + "'");
  }
}

std::string recoveryPlotTitle(const RecoveryResult& r) {
  return "Injection-recovery: " + std::to_string(r.recovered) + " of " + std::to_string(r.total) +
         " movers recovered";
}

void writeRecoveryOutputs(const RecoveryResult& r, const nlohmann::json& sets, const std::string& dir) {
  const std::filesystem::path d(dir);
  writeRecoveryCsv(r, dir);  // creates the folder
  nlohmann::json j = recoveryToJson(r);
  j["sets"] = sets;
  report::writeJsonFile((d / "recovery.json").string(), j);
  const std::string svgPath = (d / "completeness.svg").string();
  std::ofstream svg(svgPath);
  svg << completenessSvg(r.snrBins, recoveryPlotTitle(r));
  if (!svg) throw InputError("cannot write '" + svgPath + "'");
}

std::string recoveryText(const RecoveryResult& r) {
  std::string s;
  char line[256];
  std::snprintf(line, sizeof line,
                "%d of %d injected movers recovered (%.1f%%); match within %.3g px and %.3g px/s per component\n",
                r.recovered, r.total, r.total > 0 ? 100.0 * r.recovered / r.total : 0.0, r.matchPx, r.matchVPxS);
  s += line;
  auto table = [&](const char* what, const std::vector<CompletenessBin>& bins) {
    std::snprintf(line, sizeof line, "%-12s %6s %9s %13s %15s\n", what, "n", "recovered", "completeness",
                  "68% interval");
    s += line;
    for (const auto& b : bins) {
      if (b.total == 0) {
        std::snprintf(line, sizeof line, "%-12s %6d %9s %13s %15s\n", b.label.c_str(), 0, "-", "-", "-");
      } else {
        std::snprintf(line, sizeof line, "%-12s %6d %9d %13.3f   [%.3f, %.3f]\n", b.label.c_str(), b.total,
                      b.recovered, b.fraction, b.errLow, b.errHigh);
      }
      s += line;
    }
  };
  table("expected SNR", r.snrBins);
  if (!r.magBins.empty()) table("magnitude", r.magBins);
  if (r.setAsideStatic > 0) {
    std::snprintf(line, sizeof line,
                  "%d more found but set aside as static sources (moving less than about one FWHM over the "
                  "span; not counted as recovered)\n",
                  r.setAsideStatic);
    s += line;
  }
  if (r.medianSnrRatio) {
    std::snprintf(line, sizeof line, "recovered / expected SNR: median %.3f over %d recovered\n", *r.medianSnrRatio,
                  r.recovered);
    s += line;
  }
  std::snprintf(line, sizeof line, "%zu unmatched candidates", r.unmatched.size());
  s += line;
  const auto dups = std::count_if(r.unmatched.begin(), r.unmatched.end(), [](const auto& u) { return u.duplicate; });
  if (dups > 0) {
    std::snprintf(line, sizeof line, " (%td duplicates of recovered movers)", dups);
    s += line;
  }
  s += r.unmatched.empty() ? "\n" : ":\n";
  for (const auto& u : r.unmatched) {
    std::snprintf(line, sizeof line, "  set %d #%d at (%.0f, %.0f) v (%.5g, %.5g) px/s SNR %.2f%s, nearest mover %d at %.1f px\n",
                  u.set, u.candidate.index, u.candidate.xPx, u.candidate.yPx, u.candidate.vxPxS, u.candidate.vyPxS,
                  u.candidate.snr, u.duplicate ? " duplicate" : "", u.nearestId, u.nearestDistancePx);
    s += line;
  }
  return s;
}

}  // namespace st::inject

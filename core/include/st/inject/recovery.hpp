#pragma once
// Injection-recovery scoring: which injected movers (a truth file, st/inject/truth_json.hpp) did a search
// find (its candidates JSON, st/report/search_report.hpp), how complete the search is in bins of expected
// SNR and of magnitude, how much of the expected SNR it recovers, and what it found that was not injected.
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "st/inject/truth_json.hpp"

namespace st::inject {

/// One search candidate as recovery reads it.
struct CandidateRecord {
  int index = 0;  ///< 0-based position in the candidates file
  double xPx = 0.0;
  double yPx = 0.0;
  double vxPxS = 0.0;
  double vyPxS = 0.0;
  double snr = 0.0;
  std::vector<std::string> flags;
};

struct CandidateSet {
  std::optional<double> tRefMjd;     ///< the search's t_ref
  std::optional<double> gridStepPxS; ///< the search's velocity grid step (grid.step_px_s)
  std::vector<CandidateRecord> candidates;
  /// Sources the search set aside as static (SearchResult::staticSources, JSON "static_sources"): found at
  /// less than one FWHM over the span from the sky rate, so not reported as movers.
  std::vector<CandidateRecord> staticSources;
};

/// Reads the JSON that `synthtrack-cli search --json` prints (report::searchResultToJson: "candidates" with
/// x, y, vx_px_s, vy_px_s, snr, flags; "static_sources" alike, when present; t_ref_mjd; grid.step_px_s), or a
/// bare array of candidates. Throws
/// st::InputError naming the key at fault.
CandidateSet candidatesFromJson(const nlohmann::json& json);

struct RecoveryParams {
  double matchPx = 2.0;               ///< |position difference| at t_ref, px
  std::optional<double> matchVPxS;    ///< per-component velocity tolerance, px/s; none = matchVSteps grid steps
  double matchVSteps = 1.0;
  std::vector<double> snrEdges = {4, 6, 8, 10, 12, 16, 20};  ///< bins [e_i, e_i+1) and [e_last, inf)
  double magBinWidth = 0.5;           ///< magnitude bins, when every object has a magnitude
};

/// A bin of completeness: objects with lo <= value < hi, recovered / total, with the Wilson score interval
/// at 1 sigma (68.3%) as the binomial error bar.
struct CompletenessBin {
  double lo = 0.0;
  double hi = 0.0;  ///< +inf for the open last bin
  std::string label;
  int total = 0;
  int recovered = 0;
  double fraction = 0.0;  ///< recovered / total (0 when empty)
  double errLow = 0.0;    ///< Wilson interval bounds
  double errHigh = 0.0;
  double valueMean = 0.0;  ///< mean value (expected SNR or magnitude) of its objects
  double valueMin = 0.0;
  double valueMax = 0.0;
};

struct ObjectOutcome {
  int set = 0;  ///< which truth/candidates pair it came from (combineRecovery), 0 for one pair
  TruthObject truth;
  int candidate = -1;  ///< index of the matched candidate, -1 when not recovered
  double positionErrorPx = 0.0;
  double vxErrorPxS = 0.0;
  double vyErrorPxS = 0.0;
  double recoveredSnr = 0.0;
  double snrRatio = 0.0;  ///< recovered / expected SNR
  /// Not recovered as a mover but found among the search's static sources (index there; -1 otherwise):
  /// the mover moved less than about one FWHM over the span. Not counted in the completeness.
  int staticSource = -1;
  double staticSnr = 0.0;
  [[nodiscard]] bool recovered() const noexcept { return candidate >= 0; }
  [[nodiscard]] bool setAsideStatic() const noexcept { return staticSource >= 0; }
};

struct UnmatchedCandidate {
  int set = 0;
  CandidateRecord candidate;
  bool duplicate = false;      ///< within tolerance of an injected mover that another candidate matched
  int nearestId = 0;           ///< nearest truth object at t_ref (0 when there is none)
  double nearestDistancePx = 0.0;
};

struct RecoveryResult {
  double matchPx = 0.0;
  double matchVPxS = 0.0;
  double timeShiftS = 0.0;  ///< truth t_ref - search t_ref; candidates are moved to the truth's t_ref
  int total = 0;
  int recovered = 0;
  int setAsideStatic = 0;  ///< objects not recovered but found among the static sources
  std::optional<double> medianSnrRatio;
  std::vector<ObjectOutcome> objects;
  std::vector<CompletenessBin> snrBins;
  std::vector<CompletenessBin> magBins;  ///< empty unless every object has a magnitude
  std::vector<UnmatchedCandidate> unmatched;
};

/// The Wilson score interval of k successes in n trials at z standard deviations: {low, high}; {0, 1} for
/// n = 0.
std::pair<double, double> wilsonInterval(int k, int n, double z = 1.0);

/// Bins `values` (with `recovered` flags) by `edges` (increasing): [-inf, e0) only when some value lies
/// there, [e_i, e_i+1), and [e_last, +inf). Labels "A-B", ">=A", "<A". Throws st::InputError when the
/// edges are not increasing or the sizes differ.
std::vector<CompletenessBin> completenessBins(const std::vector<double>& values,
                                              const std::vector<bool>& recovered,
                                              const std::vector<double>& edges);

/// Matches candidates to truth objects one to one: a pair qualifies when the candidate's position, moved
/// to the truth's t_ref along its own velocity, is within matchPx of the object's and each velocity
/// component within the tolerance; pairs are taken in order of increasing position error (then decreasing
/// SNR), each object and candidate at most once. Candidates left over are unmatched (flagged duplicate when
/// they qualified for an object already taken). An object left unrecovered is then looked for among the
/// static sources with the same tolerances (ObjectOutcome::staticSource); static sources are never
/// unmatched candidates. Throws st::InputError when no velocity tolerance can be
/// set (no matchVPxS and no grid step in the candidates) or params are invalid.
RecoveryResult matchRecovery(const Truth& truth, const CandidateSet& candidates, const RecoveryParams& params);

/// Several injection runs scored together (e.g. one per seed): the objects and unmatched candidates of
/// `parts` (tagged with their index in `set`), totals, bins and median SNR ratio recomputed over all of them.
/// The tolerances are those of the first part; time shifts are per part and not kept.
RecoveryResult combineRecovery(const std::vector<RecoveryResult>& parts, const RecoveryParams& params);

/// The result as JSON (units in the keys): summary, snr_bins, magnitude_bins, objects, unmatched.
nlohmann::json recoveryToJson(const RecoveryResult& result);

/// Writes completeness.csv (kind = snr|magnitude, lo, hi, total, recovered, fraction, err_low, err_high),
/// objects.csv (one row per injected mover) and unmatched.csv into `dir` (created). Throws st::InputError
/// naming the file when it cannot be written.
void writeRecoveryCsv(const RecoveryResult& result, const std::string& dir);

/// The completeness plot's title that every front end uses: "Injection-recovery: K of N movers recovered".
std::string recoveryPlotTitle(const RecoveryResult& result);

/// Writes what `synthtrack-cli recovery --out DIR` writes into `dir` (created): recovery.json (recoveryToJson
/// plus "sets" = `sets`), completeness.csv, objects.csv, unmatched.csv (writeRecoveryCsv) and
/// completeness.svg (completenessSvg with recoveryPlotTitle). Throws st::InputError naming the path that
/// cannot be made or written.
void writeRecoveryOutputs(const RecoveryResult& result, const nlohmann::json& sets, const std::string& dir);

/// A short text summary for the terminal: totals, the SNR (and magnitude) table, the SNR ratio, and the
/// unmatched candidates.
std::string recoveryText(const RecoveryResult& result);

}  // namespace st::inject

// synthtrack-cli recovery TRUTH.json CANDIDATES.json: scores a search of injected frames against the
// injection's truth (core/inject: st::inject::matchRecovery), writes JSON, CSV and the completeness SVG.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "cli_args.hpp"
#include "commands.hpp"
#include "st/common/error.hpp"
#include "st/inject/recovery.hpp"

namespace st::app {
namespace {

constexpr const char* kHelp =
    "usage: synthtrack-cli recovery TRUTH.json CANDIDATES.json [TRUTH2.json CANDIDATES2.json ...]\n"
    "                               [--match-px P] [--out DIR] [options]\n\n"
    "Matches the candidates of a search (the JSON of 'synthtrack-cli search --json') to the movers of an\n"
    "injection (DIR/truth.json of 'synthtrack-cli inject'), one to one, by position at t_ref and velocity;\n"
    "prints and writes the completeness in bins of expected SNR (and of magnitude when known), with Wilson\n"
    "68% binomial intervals, the recovered/expected SNR ratio, and the unmatched candidates. Several pairs\n"
    "(e.g. one per seed) are matched pair by pair and scored together (\"set\" = the pair's index).\n\n"
    "  --match-px P           position tolerance at t_ref, px (default 2)\n"
    "  --match-v-px-s V       velocity tolerance per component, px/s (default: one grid step of the search)\n"
    "  --match-v-steps K      velocity tolerance in grid steps (default 1)\n"
    "  --snr-bins E1,E2,...   expected-SNR bin edges (default 4,6,8,10,12,16,20: bins 4-6 ... 16-20, >=20)\n"
    "  --mag-bin W            magnitude bin width (default 0.5)\n"
    "  --out DIR              write recovery.json, completeness.csv, objects.csv, unmatched.csv and\n"
    "                         completeness.svg there (default: recovery/ beside CANDIDATES.json)\n"
    "  --json                 print recovery.json to stdout instead of the table\n";

nlohmann::json readJson(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot open");
  try {
    return nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    throw InputError(path + ": not valid JSON: " + e.what());
  }
}

std::vector<double> parseEdges(const std::string& text) {
  std::vector<double> edges;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    try {
      std::size_t used = 0;
      edges.push_back(std::stod(item, &used));
      if (used != item.size()) throw std::invalid_argument(item);
    } catch (const std::exception&) {
      throw UsageError("--snr-bins needs numbers separated by commas, got '" + text + "'");
    }
  }
  if (edges.empty()) throw UsageError("--snr-bins needs at least one edge");
  return edges;
}

}  // namespace

int cmdRecovery(const Args& args) {
  const CliArgs cli(args, {"match-px", "match-v-px-s", "match-v-steps", "snr-bins", "mag-bin", "out"},
                    {"json", "help"});
  if (cli.flag("help")) {
    std::printf("%s", kHelp);
    return 0;
  }
  const auto& pos = cli.positionals();
  if (pos.size() < 2 || pos.size() % 2 != 0)
    throw UsageError("give TRUTH.json and CANDIDATES.json (or several such pairs)");
  inject::RecoveryParams params;
  params.matchPx = cli.number("match-px", 2.0);
  params.matchVPxS = cli.number("match-v-px-s");
  params.matchVSteps = cli.number("match-v-steps", 1.0);
  if (auto b = cli.value("snr-bins")) params.snrEdges = parseEdges(*b);
  params.magBinWidth = cli.number("mag-bin", 0.5);
  if (!(params.matchPx > 0.0)) throw UsageError("--match-px must be > 0");
  if (params.matchVPxS && !(*params.matchVPxS > 0.0)) throw UsageError("--match-v-px-s must be > 0");
  if (!(params.matchVSteps > 0.0)) throw UsageError("--match-v-steps must be > 0");

  std::vector<inject::RecoveryResult> parts;
  nlohmann::json sets = nlohmann::json::array();
  for (std::size_t k = 0; k < pos.size(); k += 2) {
    const std::string& truthPath = pos[k];
    const std::string& candPath = pos[k + 1];
    inject::Truth truth;
    inject::CandidateSet cands;
    try {
      truth = inject::truthFromJson(readJson(truthPath));
    } catch (const InputError& e) {
      throw InputError(truthPath + ": " + e.what());
    }
    try {
      cands = inject::candidatesFromJson(readJson(candPath));
    } catch (const InputError& e) {
      throw InputError(candPath + ": " + e.what());
    }
    parts.push_back(inject::matchRecovery(truth, cands, params));
    sets.push_back({{"set", k / 2},
                    {"truth_file", truthPath},
                    {"candidates_file", candPath},
                    {"injected", parts.back().total},
                    {"recovered", parts.back().recovered},
                    {"candidates", cands.candidates.size()},
                    {"time_shift_s", parts.back().timeShiftS}});
  }
  const inject::RecoveryResult r = parts.size() == 1 ? parts.front() : inject::combineRecovery(parts, params);
  const std::filesystem::path outDir =
      cli.value("out") ? std::filesystem::path(*cli.value("out"))
                       : std::filesystem::absolute(pos[1]).parent_path() / "recovery";
  inject::writeRecoveryOutputs(r, sets, outDir.string());
  if (cli.flag("json")) {
    nlohmann::json j = inject::recoveryToJson(r);
    j["sets"] = sets;
    std::printf("%s\n", j.dump(2).c_str());
    return 0;
  }
  if (parts.size() > 1)
    for (const auto& set : sets)
      std::printf("set %d: %d of %d recovered (%s)\n", set["set"].get<int>(), set["recovered"].get<int>(),
                  set["injected"].get<int>(), set["truth_file"].get<std::string>().c_str());
  std::printf("%s", inject::recoveryText(r).c_str());
  std::printf("wrote recovery.json, completeness.csv, objects.csv, unmatched.csv and completeness.svg in %s\n",
              outDir.string().c_str());
  return 0;
}

}  // namespace st::app

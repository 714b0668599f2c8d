#pragma once
// The subcommands of synthtrack-cli. Each lives in its own cmd_<name>.cpp, takes the arguments after its
// name and returns the process exit code: 0 success, 1 bad input or failure, 2 usage (st::app::UsageError),
// 130 cancelled. Errors are thrown; main() prints them as one line on stderr.
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace st::app {

using Args = std::vector<std::string>;

int cmdSimulate(const Args& args);
int cmdInfo(const Args& args);
int cmdConvert(const Args& args);
int cmdPreprocess(const Args& args);
int cmdStack(const Args& args);
int cmdSearch(const Args& args);
int cmdFit(const Args& args);
int cmdReport(const Args& args);
int cmdDemo(const Args& args);
int cmdBench(const Args& args);
int cmdInject(const Args& args);
int cmdRecovery(const Args& args);
int cmdBatch(const Args& args);
int cmdSolve(const Args& args);

struct ObservationInput;
struct SearchOptions;
/// `search --mpi` (mpi_search.cpp): the grid's vy rows split over the MPI ranks, rank 0 gathers, fits and
/// writes like `search`; without MPI (or outside mpirun) the same search in one process.
int searchMpi(const ObservationInput& input, const SearchOptions& options, bool fit,
              const std::optional<std::string>& csv, bool json);
/// The outputs of `search` for its result JSON: CSV to `csv` when given, then JSON or a table on stdout.
void writeSearchOutputs(const nlohmann::json& result, const std::optional<std::string>& csv, bool json);

// `synthtrack-cli bench WHAT`: each benchmark in its own bench_<what>.cpp. They print one result line per
// measurement (what, problem size, time, rate) and take --json.
int benchLoad(const Args& args);
int benchPreprocess(const Args& args);
int benchStack(const Args& args);
int benchSearch(const Args& args);
int benchFit(const Args& args);
int benchMemory(const Args& args);

}  // namespace st::app

// `synthtrack-cli search --mpi`: one cube's velocity grid split by vy rows over the MPI ranks (issue 17).
// Every rank loads and pre-processes the cube (deterministic, so all hold the same filtered frames),
// searches its share of the rows with the exact CPU kernel, and rank 0 gathers the parts, clusters them as
// one search would (st/search/row_split.hpp), fits and writes what `search` writes.
#include <cstdio>

#include "backend_factory.hpp"
#include "commands.hpp"
#include "mpi_cluster.hpp"
#include "observation_pipeline.hpp"
#include "st/search/row_split.hpp"
#include "terminal_progress.hpp"

namespace st::app {

int searchMpi(const ObservationInput& input, const SearchOptions& options, bool fit,
              const std::optional<std::string>& csv, bool json) {
  if (options.request.params.method == search::SearchMethod::Tree)
    throw UsageError("--mpi splits the exact search: give --method exact or auto");
  if (options.backend == "cuda") throw UsageError("--mpi searches on the CPU cores of every rank");
  SearchOptions o = options;
  o.request.params.method = search::SearchMethod::Exact;
  Cluster cluster;
  const bool root = cluster.rank() == 0;
  if (cluster.active()) chooseRankResources(cluster.localRank(), cluster.localSize());
  BackendSelection cpu = makeBackend(BackendChoice::Cpu);
  NullProgress quiet;
  CancelToken& cancel = processCancelToken();
  ObservationHooks hooks;
  hooks.search = [&](const search::FilteredCube& cube, const search::VelocityGrid& grid,
                     const search::SearchParams& params) {
    const search::RowRange mine = search::rowShare(grid.nvy, cluster.rank(), cluster.size());
    const search::RowSearch part = search::searchRows(cube, grid, params, mine, quiet, cancel);
    std::vector<std::string> all = cluster.gather(search::toBytes(part));
    if (!root) return search::SearchResult{};
    std::vector<search::RowSearch> parts;
    for (const auto& bytes : all)
      parts.push_back(search::rowSearchFromBytes(bytes));
    return search::mergeRowSearches(cube, grid, params, std::move(parts),
                                    "cpu (mpi: " + std::to_string(cluster.size()) + " ranks)");
  };
  if (root) {
    hooks.planned = [&](const PlannedSearch& p) {
      for (const auto& w : p.warnings)
        std::fprintf(stderr, "warning: %s\n", w.c_str());
      std::fprintf(stderr, "search --mpi: %d x %d velocities, vy rows split over %d ranks (exact, CPU)\n",
                   p.grid.nvx, p.grid.nvy, cluster.size());
    };
  }
  try {
    const nlohmann::json j = runObservation(input, o, fit && root, *cpu.backend, quiet, cancel, hooks);
    if (root) writeSearchOutputs(j, csv, json);
  } catch (const std::exception& e) {
    if (!cluster.active()) throw;
    // Another rank may wait in the gather: end the whole job.
    std::fprintf(stderr, "synthtrack-cli search --mpi: rank %d: error: %s\n", cluster.rank(), e.what());
    std::fflush(stderr);
    cluster.abort(1);
  }
  return 0;
}

}  // namespace st::app

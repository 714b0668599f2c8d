// `synthtrack-cli bench search`: throughput of the exact CPU search on an in-memory random cube, and what
// it means for the paper's problem (1500 frames x 512^2 px x 100 x 100 velocities, paper §4.4).
#include <chrono>
#include <cstdio>
#include <random>

#include <sys/resource.h>

#include "cli_args.hpp"
#include "bench_util.hpp"
#include "commands.hpp"
#include "st/common/parallel.hpp"
#include "st/search/cpu_backend.hpp"
#include "st/search/method_choice.hpp"
#include "st/search/tree_plan.hpp"
#include "st/search/tree_search.hpp"
#include "st/search/velocity_grid.hpp"
#include "terminal_progress.hpp"

namespace st::app {

namespace {

/// Paper-scale problem: 1500 frames at 16.7 Hz, 512^2 px, 100 x 100 velocities 1 px / span apart.
search::TreePlan paperPlan() {
  std::vector<double> dt(1500);
  for (std::size_t n = 0; n < dt.size(); ++n)
    dt[n] = (static_cast<double>(n) - 749.5) / 16.7;
  const double span = dt.back() - dt.front();
  return search::buildTreePlan(dt, search::VelocityGrid{{0.0, 0.0}, 1.0 / span, 100, 100});
}

struct Run {
  search::SearchResult result;
  double seconds = 0.0;
  double cpuSeconds = 0.0;
};

Run timedSearch(search::SearchBackend& backend, const search::FilteredCube& cube,
                const search::VelocityGrid& grid, const search::SearchParams& params) {
  TerminalProgress progress;
  Run run;
  const double cpu0 = processCpuSeconds();
  const auto t0 = std::chrono::steady_clock::now();
  run.result = backend.search(cube, grid, params, progress, processCancelToken());
  run.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  run.cpuSeconds = processCpuSeconds() - cpu0;
  progress.finish();
  return run;
}

/// `bench search --method tree`: the tree search and (unless --no-exact) the exact search on the same cube,
/// operation counts and times side by side, and the paper-scale extrapolation of both.
int benchTree(const search::FilteredCube& cube, const search::VelocityGrid& grid, bool runExact, bool json) {
  auto backend = search::makeCpuBackend();
  search::SearchParams params;
  params.snrThreshold = 7.0;
  const int w = cube.frames.width();
  const int h = cube.frames.height();
  const double frames = static_cast<double>(cube.frames.frameCount());
  const search::TreePlan plan = search::buildTreePlan(cube.frames.timeOffsetsS(), grid);
  const int tileRows = search::treeTileRows(plan, w);
  const double treeOps = search::treeAdditions(plan, w, h, tileRows);
  const double exactOps = static_cast<double>(w) * h * frames * grid.count();
  params.method = search::SearchMethod::Tree;
  const Run tree = timedSearch(*backend, cube, grid, params);
  Run exact;
  if (runExact) {
    params.method = search::SearchMethod::Exact;
    exact = timedSearch(*backend, cube, grid, params);
  }
  const search::TreePlan paper = paperPlan();
  const int paperRows = search::treeTileRows(paper, 512);
  const double paperTreeOps = search::treeAdditions(paper, 512, 512, paperRows);
  const double paperExactOps = 1500.0 * 512.0 * 512.0 * 100.0 * 100.0;
  const double treeRate = treeOps / tree.seconds;
  const double paperTreeS = paperTreeOps / treeRate;
  const double tileMb = static_cast<double>(search::treeTileBytes(plan, w, tileRows)) / 1048576.0;
  const double paperTileMb = static_cast<double>(search::treeTileBytes(paper, 512, paperRows)) / 1048576.0;
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  const double rssMb = static_cast<double>(u.ru_maxrss) / 1024.0;
  // What `--method auto` would choose here (method_choice.hpp), to compare with the measured winner.
  const search::MethodEstimate est =
      search::estimateMethods(w, h, cube.frames.timeOffsetsS(), grid, search::costModelFor(*backend),
                              workerCount(), 0, cube.frames.frameOffsets());
  const search::MethodChoice autoChoice =
      search::chooseMethod(search::SearchMethod::Auto, est, true, backend->name());
  const std::string autoMethod(autoChoice.method.name());
  if (json) {
    std::printf(
        "{\"bench\": \"search-tree\", \"threads\": %u, \"frames\": %.0f, \"width\": %d, \"height\": %d, "
        "\"nvx\": %d, \"nvy\": %d, \"tree_additions\": %.6g, \"tree_seconds\": %.4f, "
        "\"tree_cpu_seconds\": %.4f, \"tree_candidates\": %zu, \"tree_max_shift_error_px\": %d, "
        "\"tree_tile_rows\": %d, \"tree_tile_mb_per_thread\": %.1f, \"exact_additions\": %.6g, "
        "\"exact_seconds\": %.4f, \"exact_candidates\": %zu, \"paper_tree_additions\": %.6g, "
        "\"paper_tree_seconds\": %.2f, \"paper_exact_additions\": %.6g, \"paper_tree_tile_mb_per_thread\": "
        "%.1f, "
        "\"max_rss_mb\": %.0f, \"auto_method\": \"%s\", \"auto_exact_estimate_s\": %.4g, "
        "\"auto_tree_estimate_s\": %.4g}\n",
        workerCount(), frames, w, h, grid.nvx, grid.nvy, treeOps, tree.seconds, tree.cpuSeconds,
        tree.result.candidates.size(), std::max(plan.maxAbsErrX, plan.maxAbsErrY), tileRows, tileMb, exactOps,
        runExact ? exact.seconds : -1.0, runExact ? exact.result.candidates.size() : std::size_t{0},
        paperTreeOps, paperTreeS, paperExactOps, paperTileMb, rssMb, autoMethod.c_str(), est.exactSeconds,
        est.treeSeconds);
    return 0;
  }
  std::printf("search tree vs exact  %s  %.0f frames x %d x %d px x %d x %d velocities\n",
              backend->name().c_str(), frames, w, h, grid.nvx, grid.nvy);
  std::printf("  %-6s %14s %10s %10s %12s %11s\n", "method", "additions", "time s", "cpu s", "additions/s",
              "candidates");
  std::printf("  %-6s %14.4g %10.3f %10.3f %12.4g %11zu\n", "tree", treeOps, tree.seconds, tree.cpuSeconds,
              treeRate, tree.result.candidates.size());
  if (runExact) {
    std::printf("  %-6s %14.4g %10.3f %10.3f %12.4g %11zu\n", "exact", exactOps, exact.seconds,
                exact.cpuSeconds, exactOps / exact.seconds, exact.result.candidates.size());
    std::printf("  speed-up %.1fx in time, %.1fx in operations\n", exact.seconds / tree.seconds,
                exactOps / treeOps);
  }
  std::printf("  --method auto: %s (%s)%s\n", autoMethod.c_str(), autoChoice.reason.c_str(),
              runExact
                  ? (exact.seconds < tree.seconds ? "; measured: exact faster" : "; measured: tree faster")
                  : "");
  std::printf(
      "  tree: tree depth %d, %zu nodes, max |shift - round(v dt)| = %d px, tiles of %d rows, "
      "<= %.1f MB of partial stacks per thread; peak RSS %.0f MB\n",
      plan.depth, plan.nodes.size(), std::max(plan.maxAbsErrX, plan.maxAbsErrY), tileRows, tileMb, rssMb);
  const bool isPaper = frames == 1500.0 && w == 512 && h == 512 && grid.nvx == 100 && grid.nvy == 100;
  std::printf(
      "  paper problem 1500 x 512^2 x 100 x 100: exact %.3g additions, tree %.3g (%.0fx fewer, tiles of "
      "%d rows, <= %.0f MB per thread)\n    -> tree %s %.1f s%s\n",
      paperExactOps, paperTreeOps, paperExactOps / paperTreeOps, paperRows, paperTileMb,
      isPaper ? "measured" : "about", isPaper ? tree.seconds : paperTreeS,
      isPaper ? " (this run)" : " at this run's tree rate (extrapolated from this problem, not measured)");
  return 0;
}

}  // namespace

int benchSearch(const Args& args) {
  const CliArgs cli(args, {"frames", "size", "nv", "method"}, {"json", "help", "no-exact"});
  if (cli.flag("help")) {
    std::printf(
        "usage: synthtrack-cli bench search [--frames N] [--size N] [--nv N] [--method exact|tree] "
        "[--no-exact] [--json]\n"
        "  exact CPU search of N frames of size x size random pixels over nv x nv velocities\n"
        "  (defaults 500 frames, 512 px, 31 x 31: 1.26e11 additions), frames at 16.7 Hz like the paper,\n"
        "  grid step 1 px over the span. Reports additions/s and the paper-scale extrapolation.\n"
        "  --method tree: the tree search, then the exact search on the same cube (not with --no-exact),\n"
        "  operation counts and times side by side, what --method auto would choose (method_choice.hpp),\n"
        "  and the tree's paper-scale extrapolation.\n");
    return 0;
  }
  const long long frames = cli.integer("frames").value_or(500);
  const long long size = cli.integer("size").value_or(512);
  const long long nv = cli.integer("nv").value_or(31);
  if (frames < 2 || size < 8 || nv < 1 || size > 8192 || frames > 100000 || nv > 1000) {
    throw UsageError("need --frames >= 2, 8 <= --size <= 8192, 1 <= --nv <= 1000");
  }
  search::FilteredCube cube;
  cube.frames = FrameCube(static_cast<int>(size), static_cast<int>(size), static_cast<std::size_t>(frames));
  std::mt19937 rng(1);
  std::normal_distribution<float> noise(0.0f, 1.0f);
  for (auto& p : cube.frames.pixels())
    p = noise(rng);
  for (long long n = 0; n < frames; ++n)
    cube.frames.info()[n].mjdMid = 60000.0 + n / 16.7 / 86400.0;
  cube.sigmaF = 1.0;
  cube.psfFwhmPx = 3.0;
  const double span = cube.frames.timeSpanS();
  const search::VelocityGrid grid{{0.0, 0.0}, 1.0 / span, static_cast<int>(nv), static_cast<int>(nv)};
  const std::string name = cli.value("method").value_or("exact");
  const auto method = search::parseSearchMethod(name);
  if (method == search::SearchMethod::Tree)
    return benchTree(cube, grid, !cli.flag("no-exact"), cli.flag("json"));
  if (method != search::SearchMethod::Exact)
    throw UsageError("--method must be exact or tree, got '" + name + "'");
  search::SearchParams params;
  params.snrThreshold = 7.0;
  auto backend = search::makeCpuBackend();
  TerminalProgress progress;
  const double cpu0 = processCpuSeconds();
  const auto t0 = std::chrono::steady_clock::now();
  const search::SearchResult r = backend->search(cube, grid, params, progress, processCancelToken());
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const double cpuSeconds = processCpuSeconds() - cpu0;
  progress.finish();
  const double additions = static_cast<double>(size) * size * frames * grid.count();
  const double rate = additions / seconds;
  const double paper = 1500.0 * 512.0 * 512.0 * 100.0 * 100.0;
  if (cli.flag("json")) {
    std::printf(
        "{\"bench\": \"search\", \"backend\": \"%s\", \"threads\": %u, \"frames\": %lld, \"size\": %lld, "
        "\"nvx\": %lld, \"nvy\": %lld, \"additions\": %.6g, \"seconds\": %.4f, \"additions_per_s\": %.4g, "
        "\"cpu_seconds\": %.4f, \"paper_additions\": %.6g, \"paper_seconds\": %.1f, \"candidates\": %zu}\n",
        backend->name().c_str(), workerCount(), frames, size, nv, nv, additions, seconds, rate, cpuSeconds,
        paper, paper / rate, r.candidates.size());
  } else {
    std::printf("search exact  %s  %lld frames x %lld^2 px x %lld x %lld velocities = %.3g additions\n",
                backend->name().c_str(), frames, size, nv, nv, additions);
    std::printf("  time %.3f s   %.3g additions/s   (%zu candidates above SNR 7 in noise)\n", seconds, rate,
                r.candidates.size());
    std::printf("  cpu time %.3f s over %u threads: %.3g additions per cpu-second%s\n", cpuSeconds,
                workerCount(), additions / cpuSeconds,
                cpuSeconds < 0.8 * seconds * workerCount()
                    ? "  (machine busy: fewer cores than threads were free)"
                    : "");
    std::printf("  paper problem 1500 x 512^2 x 100 x 100 = %.3g additions -> %.0f s at this rate\n", paper,
                paper / rate);
  }
  return 0;
}

}  // namespace st::app

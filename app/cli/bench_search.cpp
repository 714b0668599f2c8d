// `synthtrack-cli bench search`: throughput of the exact CPU search on an in-memory random cube, and what
// it means for the paper's problem (1500 frames x 512^2 px x 100 x 100 velocities, paper §4.4).
#include <chrono>
#include <cstdio>
#include <random>

#include <sys/resource.h>

#include "cli_args.hpp"
#include "commands.hpp"
#include "st/common/parallel.hpp"
#include "st/search/cpu_backend.hpp"
#include "st/search/velocity_grid.hpp"
#include "terminal_progress.hpp"

namespace st::app {

namespace {

/// CPU seconds used by this process (all threads), to tell a slow machine from a busy one.
double processCpuSeconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

}  // namespace

int benchSearch(const Args& args) {
  const CliArgs cli(args, {"frames", "size", "nv"}, {"json", "help"});
  if (cli.flag("help")) {
    std::printf(
        "usage: synthtrack-cli bench search [--frames N] [--size N] [--nv N] [--json]\n"
        "  exact CPU search of N frames of size x size random pixels over nv x nv velocities\n"
        "  (defaults 500 frames, 512 px, 31 x 31: 1.26e11 additions), frames at 16.7 Hz like the paper,\n"
        "  grid step 1 px over the span. Reports additions/s and the paper-scale extrapolation.\n");
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

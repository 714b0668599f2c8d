// synthtrack-cli bench memory: the out-of-core search (issue 20) beside the in-memory one on a cube that
// fits. Writes a filtered pre-processed cube (Gaussian noise, SIGMAF 1, a few moving sources) of FRAMES x
// (W x H) float32 to a temporary folder, then runs `synthtrack-cli search CUBE --preprocessed` as a child
// process (so that each run's peak resident memory, VmHWM, is its own) in memory and with --memory-limit
// (default: a third of the cube), and prints wall time, CPU time, peak memory, tiles and whether the
// candidates are identical. The page cache is warm for both (the file was just written and read once).
// --raw does the same for raw frames whose pre-processing runs out of core (pipeline/preprocess_out_of_core).
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <random>
#include <sys/resource.h>
#include <sys/wait.h>

#include "bench_util.hpp"
#include "cli_args.hpp"
#include "commands.hpp"
#include "st/common/error.hpp"
#include "st/common/frame_cube.hpp"
#include "st/common/memory_budget.hpp"
#include "st/common/parallel.hpp"
#include "st/io/fits_writer.hpp"
#include "st/pipeline/memory_plan.hpp"
#include "st/psf/moffat.hpp"

namespace st::app {
namespace {

namespace fs = std::filesystem;

struct Run {
  double wallS = 0.0;
  double cpuS = 0.0;
  nlohmann::json j;
};

/// Runs `synthtrack-cli ARGS` as a child process (stdout, stderr to DIR/TAG.json, .err); its wall and CPU
/// time and stdout parsed as JSON (empty when `json` is false).
Run runChild(std::vector<std::string> args, const fs::path& dir, const std::string& tag, bool json = true) {
  const fs::path out = dir / (tag + ".json");
  const fs::path err = dir / (tag + ".err");
  const auto t0 = std::chrono::steady_clock::now();
  const pid_t pid = fork();
  if (pid == 0) {
    std::vector<char*> argv{const_cast<char*>("synthtrack-cli")};
    for (auto& a : args)
      argv.push_back(a.data());
    argv.push_back(nullptr);
    if (!std::freopen(out.c_str(), "w", stdout) || !std::freopen(err.c_str(), "w", stderr)) _exit(127);
    execv("/proc/self/exe", argv.data());
    _exit(127);
  }
  int status = 0;
  rusage ru{};
  if (pid < 0 || wait4(pid, &status, 0, &ru) != pid) throw InputError("bench memory: cannot run the search");
  Run r;
  r.wallS = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.cpuS = static_cast<double>(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) +
           1e-6 * static_cast<double>(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    std::ifstream in(err);
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    throw InputError("bench memory: " + args.front() + " (" + tag + ") failed: " + text);
  }
  if (json) std::ifstream(out) >> r.j;
  return r;
}

Run runSearch(const fs::path& cube, const fs::path& dir, const std::string& tag,
              const std::vector<std::string>& extra, bool preprocessed = true) {
  std::vector<std::string> args{"search", cube.string(), "--json"};
  if (preprocessed) args.push_back("--preprocessed");
  args.insert(args.end(), extra.begin(), extra.end());
  return runChild(args, dir, tag);
}

double bestSnr(const Run& r) {
  double best = 0.0;
  for (const auto& c : r.j["candidates"])
    best = std::max(best, c["snr"].get<double>());
  return best;
}

/// --raw: simulated raw frames (the simulator's small preset at FRAMES x W x H) searched with pre-processing
/// in memory and out of core (strips of rows) under a budget of half the in-memory pre-processing estimate,
/// `rounds` times alternately (a loaded machine's noise: the medians are compared).
int benchMemoryRaw(long long frames, int w, int h, const std::optional<std::string>& limitArg, int rounds) {
  const double estimate =
      pipeline::estimatePreprocessPeak({w, h, static_cast<std::size_t>(frames)}, false, workerCount()).total();
  const std::string limit =
      limitArg.value_or(std::to_string(static_cast<long long>(estimate / 2.0 / 1048576.0)) + "M");
  const fs::path dir = fs::temp_directory_path() / ("st-bench-memory-raw-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const fs::path raw = dir / "raw.fits";
  runChild({"simulate", "--preset", "small", "--frames", std::to_string(frames), "--size",
            std::to_string(w) + "x" + std::to_string(h), "-o", raw.string()},
           dir, "simulate", false);
  const std::vector<std::string> common{"--vmax-deg-day", "40", "--backend", "cpu", "--scratch", dir.string()};
  std::vector<std::string> mem = common, ooc = common;
  mem.insert(mem.end(), {"--memory-limit", "64G"});
  ooc.insert(ooc.end(), {"--memory-limit", limit});
  runSearch(raw, dir, "warm", mem, false);
  std::vector<Run> a, b;
  for (int r = 0; r < rounds; ++r) {
    a.push_back(runSearch(raw, dir, "in-memory", mem, false));
    b.push_back(runSearch(raw, dir, "out-of-core", ooc, false));
  }
  std::string plan;  // the out-of-core plan's line ("pre-processing out of core: N strips ...")
  {
    std::ifstream in(dir / "out-of-core.err");
    for (std::string l; std::getline(in, l);)
      if (l.find("pre-processing out of core:") != std::string::npos) plan = l;
  }
  fs::remove_all(dir);
  std::printf("bench memory --raw: %s, %u threads, %s\n", cpuModel().c_str(), workerCount(), utcNow().c_str());
  std::printf("problem: raw frames of the small preset, %lld x %d x %d px (%.0f MB float32), pre-processed and "
              "searched (+-40 deg/day, auto method); in-memory pre-processing estimated at %s\n",
              frames, w, h, 4.0 * w * h * static_cast<double>(frames) / 1048576.0, formatBytes(estimate).c_str());
  std::printf("%s\n", plan.c_str());
  const auto line = [](const char* name, const Run& r) {
    std::printf("  %-12s wall %7.2f s, CPU %7.2f s, peak resident %s, %zu candidates, best SNR %.2f\n", name,
                r.wallS, r.cpuS, formatBytes(r.j["memory"]["peak_resident_bytes"].get<double>()).c_str(),
                r.j["candidates"].size(), bestSnr(r));
  };
  std::printf("  (budget %s)\n", limit.c_str());
  for (int r = 0; r < rounds; ++r) {
    line("in memory", a[r]);
    line("out of core", b[r]);
  }
  const auto median = [](const std::vector<Run>& runs, double Run::*field) {
    std::vector<double> v;
    for (const auto& r : runs)
      v.push_back(r.*field);
    std::sort(v.begin(), v.end());
    return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
  };
  // The candidates of SNR >= 10 (noise peaks near the threshold of 7 may differ between the strips' and the
  // whole frame's statistics) at the same cells within 1 px.
  const auto strong = [](const Run& r) {
    std::vector<std::pair<int, int>> s;
    for (const auto& c : r.j["candidates"])
      if (c["snr"].get<double>() >= 10.0) s.emplace_back(c["x"].get<int>(), c["y"].get<int>());
    return s;
  };
  const auto sa = strong(a.back()), sb = strong(b.back());
  bool same = sa.size() == sb.size();
  for (std::size_t i = 0; same && i < sa.size(); ++i)
    same = std::abs(sa[i].first - sb[i].first) <= 1 && std::abs(sa[i].second - sb[i].second) <= 1;
  std::printf("out of core / in memory (median of %d): wall %.2fx, CPU %.2fx, peak %.2fx; best SNR %.2f vs %.2f; "
              "candidates of SNR >= 10 %s (%zu)\n",
              rounds, median(b, &Run::wallS) / median(a, &Run::wallS), median(b, &Run::cpuS) / median(a, &Run::cpuS),
              b.back().j["memory"]["peak_resident_bytes"].get<double>() /
                  a.back().j["memory"]["peak_resident_bytes"].get<double>(),
              bestSnr(b.back()), bestSnr(a.back()), same ? "at the same cells" : "DIFFER", sa.size());
  return 0;
}

}  // namespace

int benchMemory(const Args& args) {
  const CliArgs cli(args, {"frames", "size", "vmax-px-s", "memory-limit", "method", "rounds"},
                     {"help", "raw", "keep"});
  if (cli.flag("help")) {
    std::printf(
        "usage: synthtrack-cli bench memory [--frames N] [--size WxH] [--vmax-px-s V] [--method exact|tree]\n"
        "                                   [--memory-limit SIZE] [--raw [--rounds N]] [--keep]\n"
        "  in-memory vs out-of-core search of a filtered cube (default 400 x 512x512, 0.1 px/s, exact,\n"
        "  out of core under a third of the cube)\n"
        "  --raw: simulated raw frames (small preset; default 200 x 512x1024) pre-processed and searched in\n"
        "  memory and out of core (strips of rows) under half the in-memory pre-processing estimate;\n"
        "  --rounds N: both N times alternately, the ratios of the medians (default 1)\n"
        "  --keep: (not with --raw) the temporary folder (cube, each run's JSON and log) is left in place\n");
    return 0;
  }
  if (cli.flag("raw")) {
    int rw = 512, rh = 1024;
    if (auto s = cli.value("size")) {
      if (std::sscanf(s->c_str(), "%dx%d", &rw, &rh) != 2 || rw < 32 || rh < 32)
        throw UsageError("--size must be WxH with both >= 32, got '" + *s + "'");
    }
    const long long rounds = cli.integer("rounds").value_or(1);
    if (rounds < 1 || rounds > 20) throw UsageError("--rounds must be 1-20");
    return benchMemoryRaw(cli.integer("frames").value_or(200), rw, rh, cli.value("memory-limit"),
                          static_cast<int>(rounds));
  }
  const long long frames = cli.integer("frames").value_or(400);
  int w = 512, h = 512;
  if (auto s = cli.value("size")) {
    if (std::sscanf(s->c_str(), "%dx%d", &w, &h) != 2 || w < 32 || h < 32)
      throw UsageError("--size must be WxH with both >= 32, got '" + *s + "'");
  }
  if (frames < 8) throw UsageError("--frames must be >= 8");
  const double vmax = cli.number("vmax-px-s").value_or(0.1);
  const std::string method = cli.value("method").value_or("exact");
  const double cubeBytes = 4.0 * w * h * static_cast<double>(frames);
  const std::string limit = cli.value("memory-limit").value_or(
      std::to_string(static_cast<long long>(cubeBytes / 3.0 / 1048576.0)) + "M");

  const fs::path dir = fs::temp_directory_path() / ("st-bench-memory-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const fs::path path = dir / "filtered.fits";
  {
    FrameCube cube(w, h, static_cast<std::size_t>(frames));
    std::mt19937_64 rng(7);
    std::normal_distribution<float> noise(0.0f, 1.0f);
    for (auto& p : cube.pixels())
      p = noise(rng);
    for (std::size_t n = 0; n < cube.frameCount(); ++n) {
      cube.info()[n].mjdMid = 60000.0 + 0.1 * static_cast<double>(n) / 86400.0;
      cube.info()[n].exposureS = 0.1;
    }
    const psf::Moffat psf = psf::Moffat::fromFwhm(2.5, 4.0);
    const std::vector<double> dt = cube.timeOffsetsS();
    for (int k = 0; k < 6; ++k) {
      const double x0 = w * (0.15 + 0.14 * k), y0 = h * (0.8 - 0.12 * k);
      const double vx = vmax * (k % 3 - 1) * 0.6, vy = vmax * ((k + 1) % 3 - 1) * 0.5;
      for (std::size_t n = 0; n < cube.frameCount(); ++n) {
        const double xc = x0 + vx * dt[n], yc = y0 + vy * dt[n];
        for (int y = static_cast<int>(yc) - 8; y <= static_cast<int>(yc) + 8; ++y)
          for (int x = static_cast<int>(xc) - 8; x <= static_cast<int>(xc) + 8; ++x)
            if (x >= 0 && y >= 0 && x < w && y < h)
              cube.frame(n)[static_cast<std::size_t>(y) * w + x] += static_cast<float>(1.3 * psf(x - xc, y - yc));
      }
    }
    FitsHeader hd;
    hd.setNumber("STPREP", 1);
    hd.set("STFILT", "T");
    hd.setNumber("PSFFWHM", 2.5);
    hd.setNumber("PSFBETA", 4.0);
    hd.setNumber("SIGMAF", 1.0);
    io::writeCube(path.string(), cube, hd);
  }
  const std::vector<std::string> common{"--vmax-px-s", std::to_string(vmax), "--backend", "cpu", "--method", method};
  std::vector<std::string> mem = common, ooc = common;
  mem.insert(mem.end(), {"--memory-limit", "64G"});
  ooc.insert(ooc.end(), {"--memory-limit", limit});
  runSearch(path, dir, "warm", mem);  // page cache and allocator warm for both
  const Run a = runSearch(path, dir, "in-memory", mem);
  const Run b = runSearch(path, dir, "out-of-core", ooc);
  if (!cli.flag("keep")) fs::remove_all(dir);
  const bool same = a.j["candidates"] == b.j["candidates"] &&
                    a.j["cells_above_threshold"] == b.j["cells_above_threshold"];
  std::printf("bench memory: %s, %u threads, %s\n", cpuModel().c_str(), workerCount(), utcNow().c_str());
  std::printf("problem: %lld frames x %d x %d px (%.0f MB float32), %s search, |v| <= %g px/s, %d x %d "
              "velocities\n",
              frames, w, h, cubeBytes / 1048576.0, method.c_str(), vmax, a.j["trials"]["nvx"].get<int>(),
              a.j["trials"]["nvy"].get<int>());
  const auto line = [](const char* name, const Run& r) {
    std::printf("  %-12s wall %7.2f s, CPU %7.2f s, peak resident %s, %zu candidates%s\n", name, r.wallS, r.cpuS,
                formatBytes(r.j["memory"]["peak_resident_bytes"].get<double>()).c_str(), r.j["candidates"].size(),
                r.j["memory"]["out_of_core"].get<bool>()
                    ? (", " + std::to_string(r.j["memory"]["tiles"].get<int>()) + " tiles").c_str()
                    : "");
  };
  line("in memory", a);
  std::printf("  (budget %s)\n", limit.c_str());
  line("out of core", b);
  std::printf("out of core / in memory: wall %.2fx, CPU %.2fx, peak %.2fx; candidates %s\n", b.wallS / a.wallS,
              b.cpuS / a.cpuS,
              b.j["memory"]["peak_resident_bytes"].get<double>() / a.j["memory"]["peak_resident_bytes"].get<double>(),
              same ? "identical" : "DIFFER");
  return same ? 0 : 1;
}

}  // namespace st::app

// Issue 20 end to end: a filtered pre-processed cube about 3x a small --memory-limit is searched out of core
// (tiles read with CFITSIO's subset reader) and gives exactly the candidates of the in-memory search, for
// the CPU exact and tree methods, with the child process's peak resident memory (wait4's ru_maxrss) under
// the budget; a budget too small for even one tile exits 1 before the work, naming the need and the budget.
#include <gtest/gtest.h>
#include <fcntl.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>

#include "cli_runner.hpp"
#include "st/common/frame_cube.hpp"
#include "st/io/fits_writer.hpp"
#include "st/psf/moffat.hpp"
#include "test_support.hpp"

extern char** environ;

namespace st {
namespace {

using test::cliPath;
using test::readText;

constexpr int kW = 480, kH = 480;
constexpr std::size_t kFrames = 400;  // 369 MB of float32 pixels: 2.9x the budget
constexpr const char* kBudget = "128M";
constexpr std::size_t kBudgetBytes = std::size_t{128} << 20;

/// Runs the CLI with `args`, stdout and stderr to files; returns (exit status, ru_maxrss bytes). ru_maxrss of
/// a spawned child includes the parent's high-water mark (the child shares its address space until exec),
/// so the budget is checked on the child's own VmHWM, which `search` writes to the JSON.
std::pair<int, std::size_t> runMeasured(const std::vector<std::string>& args, const std::filesystem::path& out,
                                        const std::filesystem::path& err) {
  const std::string cli = cliPath().string();
  std::vector<char*> argv{const_cast<char*>(cli.c_str())};
  for (const auto& a : args)
    argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 1, out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_addopen(&fa, 2, err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  pid_t pid = 0;
  const int rc = posix_spawn(&pid, cli.c_str(), &fa, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  if (rc != 0) return {-1, 0};
  int status = 0;
  rusage ru{};
  if (wait4(pid, &status, 0, &ru) != pid) return {-1, 0};
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, static_cast<std::size_t>(ru.ru_maxrss) * 1024};
}

class OutOfCoreCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { s_dir = new test::TempDir; }

  /// Writes F.fits (filtered) or Z.fits (zero-biased) on first use: ctest runs each test in its own process.
  static void writeCube(const std::string& file) {
    if (std::filesystem::exists(path(file))) return;
    // Filtered frames: Gaussian noise (sigma 1) plus moving Moffat sources, four of them across the tile
    // borders of the out-of-core plan, one leaving the frame.
    FrameCube cube(kW, kH, kFrames);
    std::mt19937_64 rng(5);
    std::normal_distribution<float> noise(0.0f, 1.0f);
    for (auto& p : cube.pixels())
      p = noise(rng);
    for (std::size_t n = 0; n < kFrames; ++n) {
      cube.info()[n].mjdMid = 60000.0 + 0.1 * static_cast<double>(n) / 86400.0;
      cube.info()[n].exposureS = 0.1;
    }
    const psf::Moffat psf = psf::Moffat::fromFwhm(2.5, 4.0);
    struct Obj {
      double x, y, vx, vy, alpha;
    };
    const std::vector<double> dt = cube.timeOffsetsS();
    for (const Obj& o : {Obj{100, 57, 0.05, -0.03, 1.2}, Obj{300, 112, -0.04, 0.06, 1.0},
                         Obj{224, 300, 0.07, 0.0, 1.5}, Obj{470, 400, 0.08, 0.05, 1.4},
                         Obj{30, 224, 0.0, -0.06, 1.1}}) {
      for (std::size_t n = 0; n < kFrames; ++n) {
        const double xc = o.x + o.vx * dt[n], yc = o.y + o.vy * dt[n];
        for (int y = static_cast<int>(yc) - 8; y <= static_cast<int>(yc) + 8; ++y)
          for (int x = static_cast<int>(xc) - 8; x <= static_cast<int>(xc) + 8; ++x)
            if (x >= 0 && y >= 0 && x < kW && y < kH)
              cube.frame(n)[static_cast<std::size_t>(y) * kW + x] += static_cast<float>(o.alpha * psf(x - xc, y - yc));
      }
    }
    FitsHeader h;
    h.setNumber("STPREP", 1);
    h.set("STFILT", "T");
    h.setNumber("PSFFWHM", 2.5);
    h.setNumber("PSFBETA", 4.0);
    h.setNumber("SIGMAF", 1.0);
    h.setNumber("SKYVX", 0.0);
    h.setNumber("SKYVY", 0.0);
    if (file == "F.fits") io::writeCube((*s_dir / "F.fits").string(), cube, h);
    // The same frames as a zero-biased cube (filtered on loading, tile by tile with the filter's reach).
    FitsHeader z;
    z.setNumber("STPREP", 1);
    z.set("STFILT", "F");
    z.setNumber("PSFFWHM", 2.5);
    z.setNumber("PSFBETA", 4.0);
    if (file == "Z.fits") io::writeCube((*s_dir / "Z.fits").string(), cube, z);
  }
  static void TearDownTestSuite() {
    delete s_dir;
    s_dir = nullptr;
  }
  void SetUp() override {
    if (cliPath().empty()) GTEST_SKIP() << "synthtrack-cli not built";
  }
  static std::filesystem::path path(const std::string& name) { return *s_dir / name; }

  /// search F.fits --preprocessed with `extra`; (exit, peak RSS, JSON).
  static std::tuple<int, std::size_t, nlohmann::json> search(const std::string& method,
                                                             std::vector<std::string> extra,
                                                             const std::string& tag,
                                                             const std::string& file = "F.fits") {
    writeCube(file);
    std::vector<std::string> args{"search", path(file).string(), "--preprocessed", "--vmax-px-s", "0.1",
                                  "--snr", "6", "--backend", "cpu", "--method", method, "--json"};
    args.insert(args.end(), extra.begin(), extra.end());
    const auto [rc, rss] = runMeasured(args, path(tag + ".json"), path(tag + ".err"));
    nlohmann::json j;
    if (rc == 0) std::ifstream(path(tag + ".json")) >> j;
    return {rc, rss, j};
  }
  static test::TempDir* s_dir;
};
test::TempDir* OutOfCoreCli::s_dir = nullptr;

class OutOfCoreMethods : public OutOfCoreCli, public ::testing::WithParamInterface<std::string> {};

TEST_P(OutOfCoreMethods, CubeThreeTimesTheBudgetGivesTheInMemoryCandidatesWithinTheBudget) {
  const std::string method = GetParam();
  const auto [rcMem, rssMem, mem] = search(method, {}, method + "-mem");
  ASSERT_EQ(rcMem, 0) << readText(path(method + "-mem.err"));
  const auto [rcOoc, rssOoc, ooc] = search(method, {"--memory-limit", kBudget}, method + "-ooc");
  ASSERT_EQ(rcOoc, 0) << readText(path(method + "-ooc.err"));
  const std::string err = readText(path(method + "-ooc.err"));
  EXPECT_NE(err.find("out of core:"), std::string::npos) << err;
  std::printf("%s: in memory %zu candidates; --memory-limit %s: %llu tiles\n", method.c_str(),
              mem["candidates"].size(), kBudget, ooc["memory"]["tiles"].get<unsigned long long>());
  EXPECT_FALSE(mem["memory"]["out_of_core"].get<bool>());
  EXPECT_TRUE(ooc["memory"]["out_of_core"].get<bool>());
  EXPECT_GE(ooc["memory"]["tiles"].get<int>(), 3);
  // The cube alone is 3.2x the budget; the out-of-core run stays under it, the in-memory one cannot.
  const auto peakMem = mem["memory"]["peak_resident_bytes"].get<std::size_t>();
  const auto peakOoc = ooc["memory"]["peak_resident_bytes"].get<std::size_t>();
  std::printf("  VmHWM: in memory %.0f MB, out of core %.0f MB\n", peakMem / 1048576.0, peakOoc / 1048576.0);
  EXPECT_GT(peakMem, std::size_t{2} * kBudgetBytes);
  EXPECT_LT(peakOoc, kBudgetBytes);
  (void)rssMem;
  (void)rssOoc;
  // Movers and the static sources set aside (slow sources within one FWHM over the span of the sky rate).
  ASSERT_GE(mem["candidates"].size() + mem["static_sources"].size(), 4u);
  EXPECT_EQ(mem["candidates"], ooc["candidates"]);
  EXPECT_EQ(mem["static_sources"], ooc["static_sources"]);
  EXPECT_EQ(mem["cells_above_threshold"], ooc["cells_above_threshold"]);
}

INSTANTIATE_TEST_SUITE_P(Cpu, OutOfCoreMethods, ::testing::Values("exact", "tree"));

// The tree search out of core holds one tile of partial stacks per thread (issue 20): with 16 threads under
// a 128 MB budget (25^2 velocities) they alone would need ~16 x 23 MB, so the plan runs the tree on fewer
// threads (SearchParams::treeThreads); before, the plan counted them all (369 MB on a 512^2 cube) and the
// search stopped with exit 1. For 1, 2 and 16 threads (ST_THREADS) the run stays under the budget (VmHWM) and gives the
// in-memory candidates.
class OutOfCoreTreeThreads : public OutOfCoreCli, public ::testing::WithParamInterface<int> {};

TEST_P(OutOfCoreTreeThreads, TreeStaysUnderTheBudgetWhateverTheThreadCount) {
  const std::string threads = std::to_string(GetParam());
  ::setenv("ST_THREADS", threads.c_str(), 1);
  const std::vector<std::string> grid{"--vmax-px-s", "0.3"};
  auto memArgs = grid, oocArgs = grid;
  oocArgs.insert(oocArgs.end(), {"--memory-limit", kBudget});
  const auto [rcMem, rssMem, mem] = search("tree", memArgs, "threads-mem-" + threads);
  ASSERT_EQ(rcMem, 0) << readText(path("threads-mem-" + threads + ".err"));
  const auto [rcOoc, rssOoc, ooc] = search("tree", oocArgs, "threads-ooc-" + threads);
  const std::string err = readText(path("threads-ooc-" + threads + ".err"));
  ::unsetenv("ST_THREADS");
  ASSERT_EQ(rcOoc, 0) << err;
  EXPECT_TRUE(ooc["memory"]["out_of_core"].get<bool>());
  const auto peak = ooc["memory"]["peak_resident_bytes"].get<std::size_t>();
  std::printf("tree, %s threads, --memory-limit %s: VmHWM %.0f MB, %llu tiles\n", threads.c_str(), kBudget,
              peak / 1048576.0, ooc["memory"]["tiles"].get<unsigned long long>());
  EXPECT_LT(peak, kBudgetBytes) << err;
  EXPECT_EQ(mem["candidates"], ooc["candidates"]);
  EXPECT_EQ(mem["cells_above_threshold"], ooc["cells_above_threshold"]);
  (void)rssMem;
  (void)rssOoc;
}

INSTANTIATE_TEST_SUITE_P(Cpu, OutOfCoreTreeThreads, ::testing::Values(1, 2, 16));

/// The candidates of two runs are the same: positions, velocities, frame counts and every other value equal,
/// except that sums of filtered pixels (snr, sum) may differ by float rounding (1e-5 relative) and the false-
/// alarm probability by what that does to it (1e-2 relative): the CPU matched filter is an FFT, whose
/// rounding depends on the size of what is filtered, and this run filters tiles, not whole frames.
void expectSameCandidates(const nlohmann::json& a, const nlohmann::json& b, const std::string& where = "") {
  if (a.is_number_float() || b.is_number_float()) {
    ASSERT_TRUE(a.is_number() && b.is_number()) << where;
    const double x = a.get<double>(), y = b.get<double>();
    const bool fap = where.size() >= 4 && where.substr(where.size() - 4) == "/fap";
    EXPECT_LE(std::abs(x - y), (fap ? 1e-2 : 1e-5) * std::max(std::abs(x), std::abs(y)) + 1e-300)
        << where << ": " << x << " vs " << y;
    return;
  }
  if (a.is_object() && b.is_object()) {
    ASSERT_EQ(a.size(), b.size()) << where;
    for (auto it = a.begin(); it != a.end(); ++it) {
      ASSERT_TRUE(b.contains(it.key())) << where << "/" << it.key();
      expectSameCandidates(it.value(), b.at(it.key()), where + "/" + it.key());
    }
    return;
  }
  if (a.is_array() && b.is_array()) {
    ASSERT_EQ(a.size(), b.size()) << where;
    for (std::size_t i = 0; i < a.size(); ++i)
      expectSameCandidates(a[i], b[i], where + "/" + std::to_string(i));
    return;
  }
  EXPECT_EQ(a, b) << where;
}

// A zero-biased cube, cropped (the tiles are read at the crop's offset): filtered tile by tile with the
// matched filter's reach added to the overlap, the same candidates as in memory for the same sigma_F.
TEST_F(OutOfCoreCli, ZeroBiasedCroppedCubeGivesTheInMemoryCandidates) {
  const std::vector<std::string> opts{"--crop", "[1:480,101:340]", "--sigma-f", "1.3"};
  auto big = opts;
  big.insert(big.end(), {"--memory-limit", "4G"});
  auto small = opts;
  small.insert(small.end(), {"--memory-limit", "100M"});
  const auto [rcMem, rssMem, mem] = search("exact", big, "z-mem", "Z.fits");
  ASSERT_EQ(rcMem, 0) << readText(path("z-mem.err"));
  const auto [rcOoc, rssOoc, ooc] = search("exact", small, "z-ooc", "Z.fits");
  ASSERT_EQ(rcOoc, 0) << readText(path("z-ooc.err"));
  EXPECT_FALSE(mem["memory"]["out_of_core"].get<bool>());
  EXPECT_TRUE(ooc["memory"]["out_of_core"].get<bool>());
  ASSERT_GE(mem["candidates"].size(), 2u);
  expectSameCandidates(mem["candidates"], ooc["candidates"]);
  EXPECT_EQ(mem["cells_above_threshold"], ooc["cells_above_threshold"]);
  EXPECT_LT(ooc["memory"]["peak_resident_bytes"].get<std::size_t>(), std::size_t{100} << 20);
  (void)rssMem;
  (void)rssOoc;
}

TEST_F(OutOfCoreCli, BudgetTooSmallForOneTileExitsOneBeforeTheWork) {
  const auto [rc, rss, j] = search("exact", {"--memory-limit", "20M"}, "tiny");
  EXPECT_EQ(rc, 1);
  const std::string err = readText(path("tiny.err"));
  EXPECT_NE(err.find("needs"), std::string::npos) << err;
  EXPECT_NE(err.find("more than the memory budget of 20 MB (--memory-limit 20M)"), std::string::npos) << err;
  EXPECT_EQ(err.find("velocity search"), std::string::npos) << err;  // no search started
  (void)rss;
}

TEST_F(OutOfCoreCli, RawInputOverTheBudgetExitsOneNamingTheNeed) {
  const auto [rcSim, rssSim] = runMeasured(
      {"simulate", "--preset", "small", "-o", path("raw.fits").string()}, path("sim.out"), path("sim.err"));
  ASSERT_EQ(rcSim, 0) << readText(path("sim.err"));
  const auto [rc, rss] = runMeasured({"search", path("raw.fits").string(), "--backend", "cpu", "--memory-limit", "30M"},
                                     path("raw.out"), path("raw.err"));
  EXPECT_EQ(rc, 1);
  const std::string err = readText(path("raw.err"));
  // Not even a strip of rows fits (the smallest, 64 rows and the overlap, is the whole 128-row frame).
  EXPECT_NE(err.find("64 frames of 128 x 128 px: pre-processing out of core (the smallest strip of rows, 128 "
                     "rows with the overlap) needs"),
            std::string::npos)
      << err;
  EXPECT_NE(err.find("more than the memory budget of 30 MB (--memory-limit 30M)"), std::string::npos) << err;
  // The same input with room runs.
  const auto [rcOk, rssOk] = runMeasured({"search", path("raw.fits").string(), "--backend", "cpu",
                                          "--memory-limit", "1G", "--vmax-deg-day", "40"},
                                         path("rawok.out"), path("rawok.err"));
  EXPECT_EQ(rcOk, 0) << readText(path("rawok.err"));
  (void)rss;
  (void)rssOk;
}

// Raw frames whose in-memory pre-processing does not fit the budget are pre-processed out of core in strips
// of rows (pipeline/preprocess_out_of_core.hpp) and the filtered cube written to --scratch is searched: the
// simulated asteroid is found at the in-memory run's velocity and position (within a grid cell and 1 px)
// and SNR (within 5%: the strips' own meshes, sigma_F and static sources), nothing else is reported that the
// in-memory run does not report, the process stays under the budget, and the scratch cube is removed (or
// kept with --keep-scratch, a valid pre-processed cube).
TEST_F(OutOfCoreCli, RawInputOverTheBudgetIsPreProcessedOutOfCoreInStrips) {
  // The per-thread buffers count in the plan: two threads (CI's) whatever machine runs the test.
  ::setenv("ST_THREADS", "2", 1);
  const auto [rcSim, rssSim] =
      runMeasured({"simulate", "--preset", "small", "--frames", "100", "--size", "256x1024", "--seed", "3", "-o",
                   path("tall.fits").string()},
                  path("tall-sim.out"), path("tall-sim.err"));
  ASSERT_EQ(rcSim, 0) << readText(path("tall-sim.err"));
  const std::filesystem::path scratch = *s_dir / "scratch";
  std::filesystem::create_directories(scratch);
  const std::vector<std::string> common{"search", path("tall.fits").string(), "--backend", "cpu",
                                        "--centre-px-s", "3.4,1.9", "--vmax-px-s", "1", "--json"};
  auto memArgs = common;
  memArgs.insert(memArgs.end(), {"--memory-limit", "4G"});
  const auto [rcMem, rssMem] = runMeasured(memArgs, path("tall-mem.json"), path("tall-mem.err"));
  ASSERT_EQ(rcMem, 0) << readText(path("tall-mem.err"));
  constexpr std::size_t kRawBudget = std::size_t{170} << 20;
  auto oocArgs = common;
  oocArgs.insert(oocArgs.end(), {"--memory-limit", "170M", "--scratch", scratch.string(), "--keep-scratch"});
  const auto [rcOoc, rssOoc] = runMeasured(oocArgs, path("tall-ooc.json"), path("tall-ooc.err"));
  const std::string err = readText(path("tall-ooc.err"));
  ASSERT_EQ(rcOoc, 0) << err;
  EXPECT_NE(err.find("pre-processing out of core: "), std::string::npos) << err;
  nlohmann::json mem, ooc;
  std::ifstream(path("tall-mem.json")) >> mem;
  std::ifstream(path("tall-ooc.json")) >> ooc;
  EXPECT_FALSE(mem["memory"]["out_of_core"].get<bool>());
  const auto peakOoc = ooc["memory"]["peak_resident_bytes"].get<std::size_t>();
  const auto peakMem = mem["memory"]["peak_resident_bytes"].get<std::size_t>();
  std::printf("raw 100 x 256 x 1024: VmHWM in memory %.0f MB, out of core %.0f MB (budget 170 MB)\n",
              peakMem / 1048576.0, peakOoc / 1048576.0);
  EXPECT_GT(peakMem, kRawBudget);
  EXPECT_LT(peakOoc, kRawBudget);
  // The simulated asteroid (SNR ~22) and every other candidate of SNR >= 10 are found by both runs at the
  // same cell; noise peaks near the threshold of 7 may differ (sigma_F differs by the strips' 0.2%).
  const auto strong = [](const nlohmann::json& j) {
    std::vector<nlohmann::json> s;
    for (const auto& c : j["candidates"])
      if (c["snr"].get<double>() >= 10.0) s.push_back(c);
    return s;
  };
  const auto a = strong(mem), b = strong(ooc);
  ASSERT_GE(a.size(), 1u) << mem["candidates"].dump(1);
  ASSERT_EQ(b.size(), a.size()) << ooc["candidates"].dump(1);
  const double step = mem["grid"]["step_px_s"].get<double>();
  for (std::size_t i = 0; i < a.size(); ++i) {
    std::printf("  candidate (%d, %d): SNR %.2f in memory, %.2f out of core\n", a[i]["x"].get<int>(),
                a[i]["y"].get<int>(), a[i]["snr"].get<double>(), b[i]["snr"].get<double>());
    EXPECT_NEAR(b[i]["snr"].get<double>(), a[i]["snr"].get<double>(), 0.05 * a[i]["snr"].get<double>());
    EXPECT_NEAR(b[i]["x"].get<double>(), a[i]["x"].get<double>(), 1.0);
    EXPECT_NEAR(b[i]["y"].get<double>(), a[i]["y"].get<double>(), 1.0);
    EXPECT_NEAR(b[i]["vx_px_s"].get<double>(), a[i]["vx_px_s"].get<double>(), 1.01 * step);
    EXPECT_NEAR(b[i]["vy_px_s"].get<double>(), a[i]["vy_px_s"].get<double>(), 1.01 * step);
  }
  // The kept scratch cube is a filtered pre-processed cube that searches again with --preprocessed.
  const std::filesystem::path kept = scratch / "tall.synthtrack-filtered.fits";
  ASSERT_TRUE(std::filesystem::exists(kept));
  const auto [rcAgain, rssAgain] =
      runMeasured({"search", kept.string(), "--preprocessed", "--backend", "cpu", "--centre-px-s", "3.4,1.9",
                   "--vmax-px-s", "1", "--json"},
                  path("tall-again.json"), path("tall-again.err"));
  ASSERT_EQ(rcAgain, 0) << readText(path("tall-again.err"));
  nlohmann::json again;
  std::ifstream(path("tall-again.json")) >> again;
  EXPECT_EQ(again["candidates"].size(), ooc["candidates"].size());
  // Without --keep-scratch nothing is left behind, and the cube kept before is neither overwritten nor
  // removed (a temporary scratch cube has the process's own name).
  const auto keptTime = std::filesystem::last_write_time(kept);
  auto gone = common;
  gone.insert(gone.end(), {"--memory-limit", "170M", "--scratch", scratch.string()});
  const auto [rcGone, rssGone] = runMeasured(gone, path("tall-gone.json"), path("tall-gone.err"));
  EXPECT_EQ(rcGone, 0) << readText(path("tall-gone.err"));
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(scratch), std::filesystem::directory_iterator()), 1);
  EXPECT_TRUE(std::filesystem::exists(kept));
  EXPECT_EQ(std::filesystem::last_write_time(kept), keptTime);
  // --fit needs the whole cube: refused before the work, naming the need.
  auto fit = gone;
  fit.push_back("--fit");
  const auto [rcFit, rssFit] = runMeasured(fit, path("tall-fit.json"), path("tall-fit.err"));
  EXPECT_EQ(rcFit, 1);
  EXPECT_NE(readText(path("tall-fit.err")).find("--fit needs the whole zero-biased cube"), std::string::npos)
      << readText(path("tall-fit.err"));
  (void)rssSim, (void)rssMem, (void)rssOoc, (void)rssAgain, (void)rssGone, (void)rssFit;
}

}  // namespace
}  // namespace st

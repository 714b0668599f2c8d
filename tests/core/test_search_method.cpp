// Method choice (method_choice.hpp): "auto" resolves to exact for small problems and to the tree for the
// paper's, following the crossover measured with `bench search --method tree`; a backend without the tree
// gets exact with the reason; explicit requests are kept or refused with the backend named; searchWithMethod
// records the method and the reason in the result, and they reach the JSON report.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "search_test_cubes.hpp"
#include "st/common/error.hpp"
#include "st/common/parallel.hpp"
#include "st/report/search_report.hpp"
#include "st/search/cpu_backend.hpp"
#include "st/search/method_choice.hpp"
#include "st/search/tree_search.hpp"
#include "st/stack/ipsa.hpp"

namespace st::search {
namespace {

/// Frame offsets from t_ref of `frames` frames at `rateHz`, and the grid of nv x nv velocities 1 px over the
/// span apart (the paper's spacing), as `synthtrack-cli bench search` builds them.
struct Problem {
  std::vector<double> dt;
  VelocityGrid grid;
};

Problem evenProblem(int frames, double rateHz, int nv) {
  Problem p;
  p.dt.resize(static_cast<std::size_t>(frames));
  for (int n = 0; n < frames; ++n)
    p.dt[static_cast<std::size_t>(n)] = (n - 0.5 * (frames - 1)) / rateHz;
  p.grid = {{0.0, 0.0}, 1.0 / (p.dt.back() - p.dt.front()), nv, nv};
  return p;
}

MethodChoice autoOnCpu(int size, int frames, int nv, MethodEstimate* out = nullptr) {
  const Problem p = evenProblem(frames, 16.7, nv);
  const MethodEstimate e = estimateMethods(size, size, p.dt, p.grid, cpuCostModel(2), 2);
  if (out) *out = e;
  return chooseMethod(st::search::SearchMethod::Auto, e, true, "cpu (2 threads)");
}

/// A backend that says nothing about methods (so: exact only), recording what it was asked to run.
class ExactOnlyBackend final : public SearchBackend {
 public:
  std::string asked;
  [[nodiscard]] std::string name() const override { return "cuda: Fake GPU"; }
  SearchResult search(const FilteredCube& cube, const VelocityGrid& grid, const SearchParams& params,
                      ProgressSink&, CancelToken&) override {
    asked = params.method.name();
    SearchResult r;
    r.grid = grid;
    r.trials = {cube.frames.width(), cube.frames.height(), grid.nvx, grid.nvy};
    r.backend = name();
    r.method = st::search::SearchMethod::Exact;
    return r;
  }
  Image stackAt(const FilteredCube& cube, Velocity v, StackMode) override {
    return stack::stackIpsa(cube.frames, v).sum;
  }
};

FilteredCube tinyCube() {
  FilteredCube fc;
  fc.frames = test::noiseCube(32, 24, test::unevenTimes(20, 0.1, 3), 1.0, 5);
  fc.sigmaF = 1.0;
  fc.psfFwhmPx = 3.0;
  return fc;
}

struct NullProgress final : ProgressSink {
  void report(double, std::string_view) override {}
};

TEST(SearchMethod, ExplicitRequestsAreKeptOrRefusedNamingTheBackend) {
  const MethodEstimate none;
  EXPECT_EQ(chooseMethod(st::search::SearchMethod::Exact, none, true, "cpu").method, st::search::SearchMethod::Exact);
  EXPECT_EQ(chooseMethod(st::search::SearchMethod::Exact, none, true, "cpu").reason, "requested");
  EXPECT_EQ(chooseMethod(st::search::SearchMethod::Tree, none, true, "cpu").method, st::search::SearchMethod::Tree);
  EXPECT_EQ(chooseMethod(st::search::SearchMethod::Tree, none, true, "cpu").reason, "requested");
  try {
    (void)chooseMethod(st::search::SearchMethod::Tree, none, false, "cuda: Fake GPU");
    ADD_FAILURE() << "tree on a backend without it must throw";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("cuda: Fake GPU"), std::string::npos) << e.what();
  }
  // Unknown text is named where it enters (the CLI's --method, the session's "method"): parseSearchMethod
  // refuses it; a SearchMethod made from it is Unknown, which chooseMethod refuses too.
  EXPECT_FALSE(parseSearchMethod("fastest").has_value());
  EXPECT_THROW((void)chooseMethod("fastest", none, true, "cpu"), InputError);
  EXPECT_THROW((void)chooseMethod(SearchMethod::Unknown, none, true, "cpu"), InputError);
}

TEST(SearchMethodNames, TheNamesInFilesMapBothWays) {
  for (SearchMethod m : {SearchMethod::Exact, SearchMethod::Tree, SearchMethod::Auto}) {
    ASSERT_TRUE(parseSearchMethod(searchMethodName(m)).has_value()) << m;
    EXPECT_EQ(*parseSearchMethod(searchMethodName(m)), m);
  }
  EXPECT_EQ(searchMethodName(SearchMethod::Exact), "exact");
  EXPECT_EQ(searchMethodName(SearchMethod::Tree), "tree");
  EXPECT_EQ(searchMethodName(SearchMethod::Auto), "auto");
  EXPECT_FALSE(parseSearchMethod("Tree").has_value());  // names are exact, as on the command line
  EXPECT_FALSE(parseSearchMethod("").has_value());
  EXPECT_EQ(SearchMethod("tree"), SearchMethod::Tree);
  EXPECT_EQ(SearchMethod("exact "), SearchMethod::Unknown);
  SearchParams params;
  EXPECT_EQ(params.method, SearchMethod::Exact);  // the default, as before ("exact")
}

TEST(SearchMethod, SmallProblemResolvesToExact) {
  // 64 x 128^2 x 21^2: the tree needs 20x fewer additions but was slower in the bench (0.13 s vs 0.105 s).
  MethodEstimate e;
  const MethodChoice c = autoOnCpu(128, 64, 21, &e);
  EXPECT_EQ(c.method, st::search::SearchMethod::Exact) << c.reason;
  EXPECT_EQ(c.reason.rfind("auto: exact", 0), 0u) << c.reason;
  EXPECT_DOUBLE_EQ(e.exactAdditions, 128.0 * 128.0 * 64.0 * 21.0 * 21.0);
  EXPECT_GT(e.treeAdditions, 0.0);
  EXPECT_LT(e.treeAdditions, e.exactAdditions);
}

TEST(SearchMethod, PaperProblemResolvesToTree) {
  MethodEstimate e;
  const MethodChoice c = autoOnCpu(512, 1500, 100, &e);
  EXPECT_EQ(c.method, st::search::SearchMethod::Tree) << c.reason;
  EXPECT_EQ(c.reason.rfind("auto: tree", 0), 0u) << c.reason;
  EXPECT_DOUBLE_EQ(e.exactAdditions, 1500.0 * 512.0 * 512.0 * 100.0 * 100.0);
  // bench search --method tree, paper problem: 1.21e10-1.22e10 tree additions, tiles of 6 rows.
  EXPECT_NEAR(e.treeAdditions, 1.215e10, 0.02e10);
  EXPECT_EQ(e.treeTileRows, 6);
  EXPECT_LE(e.treeMaxShiftErrorPx, 1);
  EXPECT_GT(e.exactSeconds, 20.0 * e.treeSeconds);
  // Two threads' tiles within the tile budget, plus the map and N_in ranges.
  EXPECT_LE(e.treeWorkingBytes, 2 * kTreeTileBudgetBytes + (std::size_t{8} << 20));
  EXPECT_GT(e.treeWorkingBytes, kTreeTileBudgetBytes);
  EXPECT_EQ(e.cubeBytes, std::size_t{1500} * 512 * 512 * 4);
}

// Searches estimated over 10 minutes say so before they run, with the grid and what shortens it; shorter ones
// say nothing. The chosen method's estimate counts (a long exact search that auto sends to a quick tree is
// not announced).
TEST(SearchMethod, LongSearchesAreAnnouncedWithWhatShortensThem) {
  // The paper's cube over 200 x 200 velocities (twice its rates): exact ~11 min on 2 threads, the tree ~1.
  MethodEstimate paper;
  const MethodChoice tree = autoOnCpu(512, 1500, 200, &paper);
  ASSERT_EQ(tree.method, st::search::SearchMethod::Tree);
  ASSERT_GT(paper.exactSeconds, kLongSearchS);
  ASSERT_LT(paper.treeSeconds, kLongSearchS);
  const Problem p = evenProblem(1500, 16.7, 200);
  EXPECT_EQ(longSearchWarning(paper, tree, p.grid), "");
  MethodChoice exact;
  exact.method = st::search::SearchMethod::Exact;
  const std::string w = longSearchWarning(paper, exact, p.grid);
  EXPECT_NE(w.find("exact search is estimated at "), std::string::npos) << w;
  EXPECT_NE(w.find(" min here (200 x 200 velocities"), std::string::npos) << w;
  EXPECT_NE(w.find("--vmax-deg-day"), std::string::npos) << w;
  MethodEstimate hours = paper;
  hours.exactSeconds = 18700.0;  // the Lowell cube's default grid on 2 cores
  EXPECT_NE(longSearchWarning(hours, exact, p.grid).find("estimated at 5.2 h"), std::string::npos);
  EXPECT_EQ(longSearchWarning(hours, exact, p.grid, 20000.0), "");
}

TEST(SearchMethod, MidSizedProblemsFollowTheMeasuredCrossover) {
  // Measured on the 2-core VM (README): 500 x 512^2 x 15^2 exact 2.6 s, tree 0.45 s -> the tree pays;
  // 200 x 256^2 x 11^2 exact 0.24 s, tree 0.09 s -> under a second saved, exact keeps the full SNR.
  EXPECT_EQ(autoOnCpu(512, 500, 15).method, st::search::SearchMethod::Tree);
  EXPECT_EQ(autoOnCpu(256, 200, 11).method, st::search::SearchMethod::Exact);
  EXPECT_EQ(autoOnCpu(128, 30, 9).method, st::search::SearchMethod::Exact);
  // A larger grid only helps the tree: exact grows with N_v, the tree's top level about as N_v too.
  MethodEstimate small, large;
  (void)autoOnCpu(256, 500, 11, &small);
  (void)autoOnCpu(256, 500, 31, &large);
  EXPECT_GT(large.exactSeconds / large.treeSeconds, small.exactSeconds / small.treeSeconds);
}

TEST(SearchMethod, CostModelFollowsTheBackendAndTheMeasuredRate) {
  ExactOnlyBackend gpu;
  EXPECT_DOUBLE_EQ(costModelFor(gpu).exactAdditionsPerS, cudaCostModel().exactAdditionsPerS);
  auto cpu = makeCpuBackend();
  EXPECT_DOUBLE_EQ(costModelFor(*cpu).exactAdditionsPerS, cpuCostModel(workerCount()).exactAdditionsPerS);
  // A measured throughput (the GUI's live stack) prices both methods: twice the rate, half the times.
  const Problem p = evenProblem(500, 16.7, 31);
  const MethodCostModel slow = cpuCostModel(2, 1e10);
  const MethodCostModel fast = cpuCostModel(2, 2e10);
  const MethodEstimate a = estimateMethods(256, 256, p.dt, p.grid, slow, 2);
  const MethodEstimate b = estimateMethods(256, 256, p.dt, p.grid, fast, 2);
  EXPECT_NEAR(a.exactSeconds - slow.exactFixedS, 2.0 * (b.exactSeconds - fast.exactFixedS), 1e-9);
  // The exact kernel is slower on narrow images (bench: 1.44e10 additions per CPU-second at 512 px, 1.2e10 at
  // 256, 0.9e10 at 128): the same additions cost more at 256 px than at 512 px.
  const MethodEstimate wide = estimateMethods(512, 128, p.dt, p.grid, slow, 2);
  EXPECT_DOUBLE_EQ(wide.exactAdditions, a.exactAdditions);
  EXPECT_NEAR((a.exactSeconds - slow.exactFixedS) / (wide.exactSeconds - slow.exactFixedS), 1.2, 1e-9);
  EXPECT_NEAR(a.treeSeconds - slow.treeFixedS, 2.0 * (b.treeSeconds - fast.treeFixedS), 1e-9);
  // Re-pricing with the other rate gives the other estimate without rebuilding the plan.
  MethodEstimate repriced = a;
  priceMethods(repriced, fast);
  EXPECT_DOUBLE_EQ(repriced.exactSeconds, b.exactSeconds);
  EXPECT_DOUBLE_EQ(repriced.treeSeconds, b.treeSeconds);
  // On the GPU model the paper problem goes to the tree (issue 16: ~0.2 s against 0.47 s exact) where its
  // SNR loss for the PSF is small, whatever the host's threads (the device's tiles, not the CPU's, are
  // priced: 16 threads gave 2-row CPU tiles and 2.5x the additions, and auto kept the exact search).
  const Problem paper = evenProblem(1500, 16.7, 100);
  MethodEstimate g = estimateMethods(512, 512, paper.dt, paper.grid, cudaCostModel(), 1);
  const MethodEstimate g16 = estimateMethods(512, 512, paper.dt, paper.grid, cudaCostModel(), 16);
  EXPECT_DOUBLE_EQ(g16.treeAdditions, g.treeAdditions);
  EXPECT_GT(g.treeAdditions, 0.9e10);  // ~1e10 at 128-row tiles (the calibration's problem: 1.22e10)
  EXPECT_LT(g.treeAdditions, 1.25e10);
  EXPECT_NEAR(g.exactSeconds, 0.47, 0.03);
  EXPECT_LT(g.treeSeconds, 0.25);
  setPsf(g, 3.57);  // the paper-neo preset's PSF: ~1% SNR cost
  const MethodChoice onGpu = chooseMethod(st::search::SearchMethod::Auto, g, true, "cuda");
  EXPECT_EQ(onGpu.method, st::search::SearchMethod::Tree) << onGpu.reason;
  EXPECT_EQ(chooseMethod(st::search::SearchMethod::Auto, g, false, "cuda").method, st::search::SearchMethod::Exact);
  setPsf(g, 1.2);  // undersampled: the tree would lose > 3%
  EXPECT_EQ(chooseMethod(st::search::SearchMethod::Auto, g, true, "cuda").method, st::search::SearchMethod::Exact);
  // The CPU's rule is unchanged: the same estimate priced on 16 CPU threads saves under a second... or more;
  // whichever, its least saving is the CPU's second.
  EXPECT_DOUBLE_EQ(estimateMethods(512, 512, paper.dt, paper.grid, cpuCostModel(16), 16).autoTreeMinSavingS,
                   kAutoTreeMinSavingS);
  // The device's tiles are never taller than the image: a 64-row image is priced as one 64-row tile.
  const MethodEstimate low = estimateMethods(512, 64, paper.dt, paper.grid, cudaCostModel(), 16);
  EXPECT_DOUBLE_EQ(low.treeAdditions,
                   treeAdditions(*sharedTreePlan(paper.dt, paper.grid), 512, 64, 64));
  // A small GPU problem keeps the exact search: the demo's 500 x 512^2 x 45^2 (78 ms exact).
  const Problem demo = evenProblem(500, 16.7, 45);
  MethodEstimate d = estimateMethods(512, 512, demo.dt, demo.grid, cudaCostModel(), 16);
  setPsf(d, 3.56);
  EXPECT_EQ(chooseMethod(st::search::SearchMethod::Auto, d, true, "cuda").method, st::search::SearchMethod::Exact);
}

TEST(SearchMethod, NoTreePlanWithoutDistinctTimes) {
  const MethodEstimate e = estimateMethods(64, 64, {0.0, 0.0, 0.0}, {{0, 0}, 0.1, 5, 5}, cpuCostModel(2), 2);
  EXPECT_EQ(e.treeAdditions, 0.0);
  const MethodChoice c = chooseMethod(st::search::SearchMethod::Auto, e, true, "cpu");
  EXPECT_EQ(c.method, st::search::SearchMethod::Exact);
  EXPECT_NE(c.reason.find("no tree plan"), std::string::npos) << c.reason;
}

TEST(SearchMethod, BackendWithoutTreeGetsExactWithTheReason) {
  ExactOnlyBackend gpu;
  EXPECT_TRUE(gpu.supportsMethod("exact"));
  EXPECT_FALSE(gpu.supportsMethod("tree"));
  const FilteredCube fc = tinyCube();
  const VelocityGrid grid{{0.0, 0.0}, 0.5, 5, 5};
  const MethodChoice c = resolveMethod(gpu, fc, grid, SearchMethod::Auto);
  EXPECT_EQ(c.method, st::search::SearchMethod::Exact);
  EXPECT_NE(c.reason.find("cuda: Fake GPU"), std::string::npos) << c.reason;
  EXPECT_NE(c.reason.find("no tree search"), std::string::npos) << c.reason;

  NullProgress progress;
  CancelToken cancel;
  SearchParams params;
  params.method = st::search::SearchMethod::Auto;
  const SearchResult r = searchWithMethod(gpu, fc, grid, params, progress, cancel);
  EXPECT_EQ(gpu.asked, "exact");  // the backend never sees "auto"
  EXPECT_EQ(r.method, st::search::SearchMethod::Exact);
  EXPECT_EQ(r.methodReason, c.reason);
  params.method = st::search::SearchMethod::Tree;
  EXPECT_THROW((void)searchWithMethod(gpu, fc, grid, params, progress, cancel), InputError);
}

TEST(SearchMethod, CpuBackendRunsBothAndTheReportSaysWhich) {
  auto cpu = makeCpuBackend();
  EXPECT_TRUE(cpu->supportsMethod("exact"));
  EXPECT_TRUE(cpu->supportsMethod("tree"));
  EXPECT_FALSE(cpu->supportsMethod("auto"));
  const FilteredCube fc = tinyCube();
  const VelocityGrid grid{{0.0, 0.0}, 0.5, 7, 7};
  NullProgress progress;
  CancelToken cancel;
  SearchParams params;
  params.method = st::search::SearchMethod::Auto;
  const SearchResult a = searchWithMethod(*cpu, fc, grid, params, progress, cancel);
  EXPECT_EQ(a.method, st::search::SearchMethod::Exact);
  EXPECT_EQ(a.methodReason.rfind("auto: exact", 0), 0u) << a.methodReason;
  params.method = st::search::SearchMethod::Tree;
  const SearchResult t = searchWithMethod(*cpu, fc, grid, params, progress, cancel);
  EXPECT_EQ(t.method, st::search::SearchMethod::Tree);
  EXPECT_EQ(t.methodReason, "requested");
  const nlohmann::json j = report::searchResultToJson(fc, a, {"tiny.fits"});
  EXPECT_EQ(j["method"], "exact");
  EXPECT_EQ(j["method_reason"], a.methodReason);
}

}  // namespace
}  // namespace st::search

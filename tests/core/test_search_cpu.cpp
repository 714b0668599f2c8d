// The CPU exact backend against the brute-force reference, an injected moving source, pure noise,
// cancellation and progress.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <map>
#include <mutex>
#include <thread>
#include <tuple>

#include "../../core/search/ipsa_kernel.hpp"  // white-box: every cell of the kernel
#include "search_test_cubes.hpp"
#include "st/common/error.hpp"
#include "st/search/cpu_backend.hpp"
#include "st/search/ipsa.hpp"
#include "st/search/search_run.hpp"
#include "st/search/velocity_grid.hpp"
#include "st/stats/false_alarm.hpp"

namespace st::search {
namespace {

FilteredCube smallRandomCube(int w, int h, std::size_t frames, unsigned seed, bool shuffle) {
  FilteredCube fc;
  fc.frames = test::noiseCube(w, h, test::unevenTimes(frames, 0.7, seed, shuffle), 1.0, seed);
  fc.sigmaF = 1.0;
  fc.psfFwhmPx = 2.0;
  return fc;
}

// Every cell of the search (threshold -inf, no cap) against ipsaReference: N_in exactly, S to float
// rounding (|S - S_ref| <= 1e-5 * sum |F| over the frames, sums of ~20 unit-variance floats).
void expectMatchesBruteForce(const FilteredCube& fc, const VelocityGrid& grid, double minFrameFraction) {
  SearchParams params;
  params.snrThreshold = -1e30;
  params.maxCandidates = 16;  // the map and the cell count are what is compared here
  params.minFrameFraction = minFrameFraction;
  const std::size_t cells = static_cast<std::size_t>(fc.frames.width()) * fc.frames.height() * grid.count();
  auto backend = makeCpuBackend();
  NullProgress progress;
  CancelToken cancel;
  // Clustering would merge cells, so compare the raw cells through the map and a per-cell run.
  const SearchResult r = backend->search(fc, grid, params, progress, cancel);
  const std::vector<double> dt = fc.frames.timeOffsetsS();
  const int minFrames = minFramesFor(params, fc.frames.timeOffsetsS(), fc.frames.width(), fc.frames.height(), grid);
  EXPECT_EQ(r.minFrames, minFrames);
  std::int64_t expectedCells = 0;
  for (int iy = 0; iy < grid.nvy; ++iy) {
    for (int ix = 0; ix < grid.nvx; ++ix) {
      const Velocity v = grid.at(ix, iy);
      double best = -1e300;
      for (int y = 0; y < fc.frames.height(); ++y) {
        for (int x = 0; x < fc.frames.width(); ++x) {
          const IpsaCell c = ipsaReference(fc.frames, dt, x, y, v);
          if (c.nIn < minFrames || c.nIn == 0) continue;
          ++expectedCells;
          best = std::max(best, c.sum / (fc.sigmaF * std::sqrt(double(c.nIn))));
        }
      }
      const std::size_t iv = static_cast<std::size_t>(iy) * grid.nvx + ix;
      if (best > -1e300) {
        EXPECT_NEAR(r.map.maxSnr[iv], best, 1e-4) << "velocity " << ix << "," << iy;
        const IpsaCell at = ipsaReference(fc.frames, dt, r.map.argX[iv], r.map.argY[iv], v);
        EXPECT_NEAR(at.sum / std::sqrt(double(at.nIn)), best, 1e-4);
      }
    }
  }
  EXPECT_EQ(r.cellsAboveThreshold, expectedCells);
  EXPECT_LE(expectedCells, static_cast<std::int64_t>(cells));
}

TEST(SearchCpu, MapMatchesBruteForceWithSamplesOutOfFrame) {
  // 37 x 29 px, 21 uneven frames over ~17 s; grid up to +-1.5 px/s centred off zero: shifts up to ~15 px,
  // so many samples fall outside the frame and N_in varies across the image.
  const FilteredCube fc = smallRandomCube(37, 29, 21, 11, false);
  VelocityGrid grid{{0.3, -0.2}, 0.25, 13, 11};
  expectMatchesBruteForce(fc, grid, 0.0);
  expectMatchesBruteForce(fc, grid, 0.5);
}

TEST(SearchCpu, UnsortedFrameTimesGiveTheSameStatistic) {
  const FilteredCube fc = smallRandomCube(23, 40, 17, 5, true);
  VelocityGrid grid{{-0.4, 0.6}, 0.3, 7, 9};
  expectMatchesBruteForce(fc, grid, 0.3);
}

// Every cell value and N_in exactly, through hits (threshold -inf, clustering bypassed by reading the
// kernel's cells via the exported statistic on single velocities).
TEST(SearchCpu, EveryCellSumAndNinMatchBruteForce) {
  const FilteredCube fc = smallRandomCube(41, 19, 15, 23, false);
  const std::vector<double> dt = fc.frames.timeOffsetsS();
  auto backend = makeCpuBackend();
  const Velocity vs[] = {{0.0, 0.0}, {1.7, -0.9}, {-2.9, 2.2}, {0.51, 0.49}};
  for (const Velocity v : vs) {
    const Image img = backend->stackAt(fc, v, StackMode::Ipsa);
    double sumAbs = 0.0;
    for (int y = 0; y < 19; ++y) {
      for (int x = 0; x < 41; ++x) {
        const IpsaCell c = ipsaReference(fc.frames, dt, x, y, v);
        EXPECT_NEAR(img.at(x, y), c.sum, 1e-4) << x << "," << y;
        sumAbs += std::abs(c.sum);
      }
    }
    EXPECT_GT(sumAbs, 0.0);
    // Single-velocity grid: every cell reported, with N_in.
    SearchParams params;
    params.snrThreshold = -1e30;
    params.maxCandidates = 1u << 30;
    params.minFrameFraction = 0.0;
    NullProgress progress;
    CancelToken cancel;
    const SearchResult r = backend->search(fc, VelocityGrid{v, 0.1, 1, 1}, params, progress, cancel);
    std::int64_t inFrame = 0;
    for (int y = 0; y < 19; ++y) {
      for (int x = 0; x < 41; ++x)
        inFrame += ipsaReference(fc.frames, dt, x, y, v).nIn > 0;
    }
    EXPECT_EQ(r.cellsAboveThreshold, inFrame);
  }
  EXPECT_THROW(backend->stackAt(fc, {0, 0}, StackMode::Csa), InputError);
}

// Every cell of the tiled kernel (threshold -inf, no cap) against ipsaReference: N_in exactly, S within
// 1e-4 (float sums of ~20 unit-variance samples against double), on a sub-region too (confirmation).
TEST(SearchCpu, KernelEveryCellMatchesBruteForce) {
  const FilteredCube fc = smallRandomCube(45, 23, 19, 31, true);
  const VelocityGrid grid{{0.5, -0.3}, 0.35, 9, 7};
  const std::vector<double> dt = fc.frames.timeOffsetsS();
  const detail::Roi rois[] = {{0, 0, 45, 23}, {7, 3, 13, 11}};
  for (const detail::Roi& roi : rois) {
    detail::KernelParams kp;
    kp.sigmaF = 1.0;
    kp.snrThreshold = -1e30;
    kp.minFrames = 1;
    kp.maxHits = 1u << 30;
    NullProgress progress;
    CancelToken cancel;
    const detail::KernelOutput out = detail::runIpsaKernel(fc.frames, grid, roi, kp, progress, cancel);
    std::int64_t expected = 0;
    std::map<std::tuple<int, int, int, int>, IpsaCell> ref;
    for (int iy = 0; iy < grid.nvy; ++iy) {
      for (int ix = 0; ix < grid.nvx; ++ix) {
        for (int y = roi.y0; y < roi.y0 + roi.height; ++y) {
          for (int x = roi.x0; x < roi.x0 + roi.width; ++x) {
            const IpsaCell c = ipsaReference(fc.frames, dt, x, y, grid.at(ix, iy));
            if (c.nIn == 0) continue;
            ++expected;
            ref[{x, y, ix, iy}] = c;
          }
        }
      }
    }
    ASSERT_EQ(out.hitsTotal, expected);
    ASSERT_EQ(out.hits.size(), static_cast<std::size_t>(expected));
    int partial = 0;
    for (const CellHit& h : out.hits) {
      const auto it = ref.find({h.x, h.y, h.ivx, h.ivy});
      ASSERT_NE(it, ref.end());
      EXPECT_EQ(h.nIn, it->second.nIn);
      EXPECT_NEAR(h.sum, it->second.sum, 1e-4);
      EXPECT_NEAR(h.snr, it->second.sum / std::sqrt(double(h.nIn)), 1e-4);
      partial += h.nIn < 19;
    }
    if (roi.width == 45) {
      EXPECT_GT(partial, 1000);  // the boundary really was exercised
    }
  }
}

/// The cube of FindsInjectedMovingSource: 72 x 64 px, 60 uneven frames over ~40 s, white noise sigma 1, a
/// Moffat PSF of FWHM ~3 px; the grid 31 x 31 at 1 px over the span around 0. `inject` adds sources of
/// expected SNR 18 (at given positions and velocities) before the matched filter.
struct InjectedCube {
  psf::Moffat psf{psf::Moffat::radiusForFwhm(3.0, 4.0), 4.0};
  int r = 6;
  FilteredCube fc;
  VelocityGrid grid;
  double alpha = 0.0;
  InjectedCube() {
    fc.frames = test::noiseCube(72, 64, test::unevenTimes(60, 0.6, 3), 1.0, 99);
    grid = {{0.0, 0.0}, 1.0 / fc.frames.timeSpanS(), 31, 31};
    alpha = 18.0 / (std::sqrt(60.0) * std::sqrt(test::sumP2(psf, r)));
  }
  void inject(double x, double y, Velocity v) { test::injectMoffat(fc.frames, psf, alpha, x, y, v); }
  FilteredCube& filtered() {
    test::matchedFilter(fc.frames, psf, r);
    fc.sigmaF = std::sqrt(test::sumP2(psf, r));  // white noise through the filter
    fc.psfFwhmPx = psf.fwhm();
    return fc;
  }
};

// The minimum N_in follows what a track can have: one crossing the frame in a third of the span is inside for
// a third of the frames, and half of all frames (the old rule) made it unfindable. Oracles: counting by hand,
// and an injected fast mover found at its place and velocity.
TEST(SearchCpu, MinimumFramesFollowWhatATrackCanStayInside) {
  std::vector<double> t(90);
  for (std::size_t k = 0; k < t.size(); ++k)
    t[k] = static_cast<double>(k);  // 1 s apart, span 89 s
  EXPECT_EQ(maxFramesInside(t, 64, 64, {0.5, 0.2}), 90) << "stays in for the span";
  EXPECT_EQ(maxFramesInside(t, 64, 64, {2.0, 0.0}), 33) << "64 px at 2 px/s: 32 s, frames 0..32";
  EXPECT_EQ(maxFramesInside(t, 64, 32, {1.0, -2.0}), 17) << "the height limits: 16 s";
  SearchParams params;  // minFrameFraction 0.5
  const VelocityGrid slow{{0.0, 0.0}, 0.01, 5, 5};
  EXPECT_EQ(minFramesFor(params, t, 64, 64, slow), minFramesFor(params, t.size())) << "unchanged: 45";
  const VelocityGrid fast{{2.0, 0.0}, 1.0 / 89.0, 5, 5};
  // Fastest corner vx = 2 + 2/89: 64 / 2.0225 = 31.6 s, 32 frames; half of them.
  EXPECT_EQ(minFramesFor(params, t, 64, 64, fast), 16);

  FilteredCube fc;
  fc.frames = test::noiseCube(64, 64, t, 1.0, 7);
  const psf::Moffat psf{psf::Moffat::radiusForFwhm(3.0, 4.0), 4.0};
  const int r = 6;
  // SNR ~20 over the ~32 frames it is inside.
  const double alpha = 20.0 / (std::sqrt(32.0) * std::sqrt(test::sumP2(psf, r)));
  test::injectMoffat(fc.frames, psf, alpha, 30.0, 30.0, {2.0, 0.0});
  test::matchedFilter(fc.frames, psf, r);
  fc.sigmaF = std::sqrt(test::sumP2(psf, r));
  fc.psfFwhmPx = psf.fwhm();
  NullProgress progress;
  CancelToken cancel;
  const SearchResult res = makeCpuBackend()->search(fc, fast, params, progress, cancel);
  EXPECT_EQ(res.minFrames, 16);
  ASSERT_FALSE(res.candidates.empty()) << "a mover inside for a third of the frames is found";
  const Candidate& c = res.candidates.front();
  EXPECT_NEAR(c.x, 30.0, 1.0);
  EXPECT_NEAR(c.y, 30.0, 1.0);
  // The velocity to 1 px over the 32 s it is inside (the grid's step is 1 px over the whole span).
  EXPECT_NEAR(c.v.vx, 2.0, 1.0 / 32.0);
  EXPECT_GT(c.snr, 15.0);
  EXPECT_LE(c.nIn, 33);
}

// A source moving with the stars (less than one FWHM over the span from the sky rate) cannot be told from a
// star: it is set aside as a static source, not reported as a mover; a mover in the same cube is reported.
// Oracle: the injected velocities. Same cube as below, with a sky rate of (0.2, -0.1) px/s.
TEST(SearchCpu, SourcesAtTheSkyRateAreSetAsideAsStatic) {
  InjectedCube cube;
  const double span = cube.fc.frames.timeSpanS();
  const VelocityGrid& grid = cube.grid;
  cube.fc.skyRate = grid.at(17, 13);
  cube.inject(40.0, 30.0, grid.at(24, 9));
  cube.inject(15.0, 45.0, cube.fc.skyRate);
  const FilteredCube& fc = cube.filtered();
  NullProgress progress;
  CancelToken cancel;
  const SearchResult res = makeCpuBackend()->search(fc, grid, SearchParams{}, progress, cancel);
  ASSERT_EQ(res.candidates.size(), 1u);
  EXPECT_NEAR(res.candidates[0].x, 40, 1);
  EXPECT_NEAR(res.candidates[0].y, 30, 1);
  ASSERT_EQ(res.staticSources.size(), 1u);
  const Candidate& st = res.staticSources[0];
  EXPECT_NEAR(st.x, 15, 1);
  EXPECT_NEAR(st.y, 45, 1);
  EXPECT_LE(std::hypot(st.v.vx - fc.skyRate.vx, st.v.vy - fc.skyRate.vy), fc.psfFwhmPx / span);
  EXPECT_GT(st.snr, 0.8 * 18.0);
}

TEST(SearchCpu, FindsInjectedMovingSource) {
  // 72 x 64 px, 60 uneven frames over ~40 s, white noise sigma 1, Moffat FWHM ~3 px moving at a grid
  // velocity; frames matched-filtered with the PSF like pre-processing. Expected SNR (paper detection_snr)
  // alpha sqrt(N) sqrt(sum P^2) / sigma = 18; IPSA's integer shifts lose a little (samples up to 0.5 px off
  // the track), so the search SNR must be within [0.8, 1.1] of it.
  InjectedCube cube;
  const VelocityGrid& grid = cube.grid;
  cube.inject(40.0, 30.0, grid.at(24, 9));
  const FilteredCube& fc = cube.filtered();
  auto backend = makeCpuBackend();
  NullProgress progress;
  CancelToken cancel;
  SearchParams params;  // SNR 7
  const SearchResult res = backend->search(fc, grid, params, progress, cancel);
  ASSERT_EQ(res.candidates.size(), 1u);
  const Candidate& c = res.candidates[0];
  EXPECT_NEAR(c.x, 40, 1);
  EXPECT_NEAR(c.y, 30, 1);
  EXPECT_LE(std::abs(c.ivx - 24), 1);
  EXPECT_LE(std::abs(c.ivy - 9), 1);
  EXPECT_GT(c.snr, 0.8 * 18.0);
  EXPECT_LT(c.snr, 1.1 * 18.0);
  EXPECT_EQ(c.nIn, 60);
  EXPECT_GT(c.clusterCells, 1);
  EXPECT_LT(c.fap, 1e-40);
  const std::size_t iv = static_cast<std::size_t>(c.ivy) * grid.nvx + c.ivx;
  EXPECT_FLOAT_EQ(res.map.maxSnr[iv], static_cast<float>(c.snr));
}

TEST(SearchCpu, PureNoiseFalseAlarmCountMatchesProbFalse) {
  // 96 x 96 px, 32 frames, 9 x 9 velocities 3 px apart over the span (so cells decorrelate), threshold 3:
  // expected cells above = 96^2 x 81 x Q(3) = 1007.6. Cells are correlated (shared samples), so allow 30%.
  FilteredCube fc = smallRandomCube(96, 96, 32, 7, false);
  const VelocityGrid grid{{0.0, 0.0}, 3.0 / fc.frames.timeSpanS(), 9, 9};
  SearchParams params;
  params.snrThreshold = 3.0;
  params.minFrameFraction = 0.0;
  auto backend = makeCpuBackend();
  NullProgress progress;
  CancelToken cancel;
  const SearchResult r = backend->search(fc, grid, params, progress, cancel);
  const double expected = stats::expectedFalseAlarms(3.0, r.trials.total());
  EXPECT_NEAR(expected, 1007.6, 0.1);
  EXPECT_NEAR(static_cast<double>(r.cellsAboveThreshold) / expected, 1.0, 0.3);
  EXPECT_EQ(r.trials.nx, 96);
  EXPECT_EQ(r.trials.nvy, 9);
}

TEST(SearchCpu, TargetFapSetsThresholdFromTrials) {
  FilteredCube fc = smallRandomCube(32, 32, 10, 1, false);
  const VelocityGrid grid{{0.0, 0.0}, 0.1, 5, 5};
  SearchParams params;
  params.targetFap = 0.01;
  auto backend = makeCpuBackend();
  NullProgress progress;
  CancelToken cancel;
  const SearchResult r = backend->search(fc, grid, params, progress, cancel);
  EXPECT_NEAR(r.snrThreshold, stats::snrThresholdForFap(0.01, 32.0 * 32 * 25), 1e-12);
  for (const auto& c : r.candidates)
    EXPECT_GT(c.snr, r.snrThreshold);
}

struct RecordingProgress final : ProgressSink {
  std::mutex m;
  std::vector<double> values;
  void report(double f, std::string_view) override {
    std::lock_guard lock(m);
    values.push_back(f);
  }
};

/// Cancels its token at the first progress report after work started (so the test does not depend on the
/// machine's speed) and remembers when.
struct CancellingProgress final : ProgressSink {
  CancelToken& token;
  std::mutex m;
  std::vector<double> values;
  std::chrono::steady_clock::time_point cancelledAt;
  explicit CancellingProgress(CancelToken& t) : token(t) {}
  void report(double f, std::string_view) override {
    std::lock_guard lock(m);
    values.push_back(f);
    if (f > 0.0 && !token.cancelled()) {
      cancelledAt = std::chrono::steady_clock::now();
      token.cancel();
    }
  }
};

TEST(SearchCpu, CancelsPromptlyAndReportsProgress) {
  FilteredCube fc = smallRandomCube(256, 256, 200, 2, false);
  const VelocityGrid grid{{0.0, 0.0}, 0.05, 41, 41};  // ~2.2e10 additions: seconds on any machine
  auto backend = makeCpuBackend();
  CancelToken cancel;
  CancellingProgress progress(cancel);
  EXPECT_THROW(backend->search(fc, grid, SearchParams{}, progress, cancel), Cancelled);
  const auto done = std::chrono::steady_clock::now();
  ASSERT_TRUE(cancel.cancelled());
  // Every thread stops at its next frame block (< 1 ms of work); 0.5 s leaves room for a loaded machine.
  EXPECT_LT(std::chrono::duration<double>(done - progress.cancelledAt).count(), 0.5);
  ASSERT_GE(progress.values.size(), 2u);
  EXPECT_LT(progress.values.back(), 0.1);
}

TEST(SearchCpu, ProgressEndsAtOne) {
  FilteredCube fc = smallRandomCube(40, 40, 12, 4, false);
  auto backend = makeCpuBackend();
  RecordingProgress progress;
  CancelToken cancel;
  backend->search(fc, VelocityGrid{{0, 0}, 0.1, 9, 9}, SearchParams{}, progress, cancel);
  ASSERT_FALSE(progress.values.empty());
  EXPECT_DOUBLE_EQ(progress.values.back(), 1.0);
}

TEST(SearchCpu, RejectsBadInput) {
  auto backend = makeCpuBackend();
  NullProgress progress;
  CancelToken cancel;
  FilteredCube one = smallRandomCube(8, 8, 1, 1, false);
  EXPECT_THROW(backend->search(one, VelocityGrid{{0, 0}, 0.1, 3, 3}, SearchParams{}, progress, cancel),
               InputError);
  FilteredCube fc = smallRandomCube(8, 8, 4, 1, false);
  EXPECT_THROW(backend->search(fc, VelocityGrid{{0, 0}, 0.0, 3, 3}, SearchParams{}, progress, cancel),
               InputError);
  EXPECT_THROW(backend->search(fc, VelocityGrid{{0, 0}, 0.1, 0, 3}, SearchParams{}, progress, cancel),
               InputError);
  fc.sigmaF = 0.0;
  EXPECT_THROW(backend->search(fc, VelocityGrid{{0, 0}, 0.1, 3, 3}, SearchParams{}, progress, cancel),
               InputError);
  FilteredCube same = smallRandomCube(8, 8, 3, 1, false);
  for (auto& i : same.frames.info())
    i.mjdMid = 60000.0;
  EXPECT_THROW(backend->search(same, VelocityGrid{{0, 0}, 0.1, 3, 3}, SearchParams{}, progress, cancel),
               InputError);
}

}  // namespace
}  // namespace st::search

namespace st::search {
namespace {

TEST(SearchCpu, ShiftRoundsHalfAwayFromZeroLikeLround) {
  const double ps[] = {
      0.5,       -0.5,       1.5,       -1.5, 2.5, -2.5, 0.49999999999999994, -0.49999999999999994,
      1e9 + 0.5, -3.4999999, 3.5000001, 0.0,  -0.0};
  for (const double p : ps)
    EXPECT_EQ(ipsaShift(p, 1.0), static_cast<int>(std::lround(p))) << p;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-300.0, 300.0);
  for (int i = 0; i < 100000; ++i) {
    const double v = u(rng);
    const double dt = u(rng) / 7.0;
    ASSERT_EQ(ipsaShift(v, dt), static_cast<int>(std::lround(v * dt))) << v << " " << dt;
  }
}

}  // namespace
}  // namespace st::search

namespace st::search {
namespace {

TEST(SearchCpu, HugeShiftsAreOutOfFrameNotOutOfMemory) {
  // A velocity that moves samples ~1e9 px: every sample but the one at t_ref's nearest frame is out.
  const FilteredCube fc = smallRandomCube(20, 20, 9, 3, false);
  const VelocityGrid grid{{1e8, -1e8}, 1.0, 3, 3};
  SearchParams params;
  params.snrThreshold = -1e30;
  params.minFrameFraction = 0.0;
  auto backend = makeCpuBackend();
  NullProgress progress;
  CancelToken cancel;
  const SearchResult r = backend->search(fc, grid, params, progress, cancel);
  const std::vector<double> dt = fc.frames.timeOffsetsS();
  std::int64_t expected = 0;
  for (int iy = 0; iy < 3; ++iy) {
    for (int ix = 0; ix < 3; ++ix) {
      for (int y = 0; y < 20; ++y) {
        for (int x = 0; x < 20; ++x)
          expected += ipsaReference(fc.frames, dt, x, y, grid.at(ix, iy)).nIn > 0;
      }
    }
  }
  EXPECT_EQ(r.cellsAboveThreshold, expected);
  EXPECT_EQ(ipsaShift(1e300, 1.0), 1 << 30);
  EXPECT_EQ(ipsaShift(-1e300, 1.0), -(1 << 30));
}

}  // namespace
}  // namespace st::search

namespace st::search {
namespace {

TEST(SearchClustering, LinksWithinRadiiAndChains) {
  const VelocityGrid grid{{0, 0}, 0.1, 20, 20};
  ClusterParams p;
  p.positionRadiusPx = 4.0;
  p.velocityRadiusSteps = 2;
  std::vector<CellHit> cells = {
      {9.0f, 0, 10, 10, 5, 5, 10},  // A: best of cluster 1
      {8.0f, 0, 13, 10, 6, 5, 10},  // links to A (dx 3, dv 1)
      {7.5f, 0, 17, 10, 8, 5, 10},  // links to the previous (dx 4, dv 2), not to A: chained
      {7.2f, 0, 22, 10, 8, 5, 10},  // dx 5 from its nearest: separate
      {8.5f, 0, 14, 10, 9, 5, 10},  // dv 4 from A, (dx 3, dv 1) from the 7.5 cell: chained too
      {7.1f, 0, 50, 50, 0, 0, 10},  // far away: separate
  };
  const std::vector<Candidate> c = clusterCells(cells, grid, p, TrialCounts{100, 100, 20, 20});
  ASSERT_EQ(c.size(), 3u);
  EXPECT_EQ(c[0].x, 10);
  EXPECT_FLOAT_EQ(static_cast<float>(c[0].snr), 9.0f);
  EXPECT_EQ(c[0].clusterCells, 4);
  EXPECT_EQ(c[1].x, 22);
  EXPECT_EQ(c[2].x, 50);
  EXPECT_EQ(c[2].clusterCells, 1);
  EXPECT_DOUBLE_EQ(c[0].v.vx, grid.at(5, 5).vx);
  EXPECT_NEAR(c[0].fap, stats::detectionFap(9.0, 100, 100, 20, 20), 1e-30);
  // A dense block of cells (a bright source) is one candidate, and fast.
  std::vector<CellHit> dense;
  for (int y = 0; y < 60; ++y)
    for (int x = 0; x < 60; ++x)
      for (int v = 0; v < 100; ++v)
        dense.push_back({static_cast<float>(x + y + v), 0, x, y, v % 10, v / 10, 10});
  const auto d = clusterCells(dense, grid, p, TrialCounts{100, 100, 20, 20});
  ASSERT_EQ(d.size(), 1u);
  EXPECT_EQ(d[0].clusterCells, 360000);
  EXPECT_EQ(d[0].x, 59);
}

}  // namespace
}  // namespace st::search

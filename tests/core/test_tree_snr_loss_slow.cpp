// The tree search's SNR cost against the exact search (issue 16, part 3) on matched-filtered injected
// objects: Moffat (beta 4) sources of FWHM 1.5, 2, 2.5 and 3.5 px at their true sub-pixel positions (not
// rounded to the IPSA shifts), white noise, the paper's cadence (16.7 Hz) and grid design (neighbouring
// velocities 1 px apart at the ends of the span), both searches on the CPU. The loss of an object is
// 1 - S_tree / S_exact at its best cell (within 2 px and 1.5 grid steps of the truth), without noise (the
// tracks' loss alone, not a draw of the noise), on the paper's problem's tree (1500 frames, 100 x 100
// velocities: tracks within 2 px of the exact ones) over a 128 x 96 image; per FWHM the worst of 12
// objects is held against search::treeSnrLoss (the table `auto` uses, method_choice.hpp) within 0.6
// percentage points, and it must not grow as the PSF widens. ~35 CPU-s (labelled slow).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

#include "st/psf/moffat.hpp"
#include "st/search/cpu_backend.hpp"
#include "st/search/method_choice.hpp"
#include "st/search/tree_plan.hpp"
#include "st/search/tree_search.hpp"
#include "st/stack/ipsa.hpp"
#include "st/stack/matched_filter.hpp"

namespace st {
namespace {

struct Truth {
  double x, y;
  Velocity v;
};

struct LossResult {
  double median = 0.0, worst = 0.0;
  int matched = 0;
  int maxShiftErr = 0;
};

/// The tree's loss on `objects` noise-free filtered Moffat sources of FWHM `fwhm` in `n` frames at 16.7 Hz,
/// grid of nv x nv velocities 1 px apart at the ends of the span: S_tree / S_exact, each the largest sum
/// within 2 px and 1.5 grid steps of the truth (exact: IPSA stacks at those grid velocities; tree: its
/// candidates' sums).
LossResult measureLoss(double fwhm, int n, int nv, unsigned seed) {
  const int w = 128, h = 96;
  const double cadence = 1.0 / 16.7;
  search::FilteredCube cube;
  cube.frames = FrameCube(w, h, n);
  for (int k = 0; k < n; ++k)
    cube.frames.info()[k].mjdMid = 60000.0 + k * cadence / kSecondsPerDay;
  std::mt19937 rng(seed);
  const std::vector<double> dt = cube.frames.timeOffsetsS();
  const double span = dt.back() - dt.front();
  const search::VelocityGrid grid{{0.0, 0.0}, 2.0 / span, nv, nv};
  const psf::Moffat psf = psf::Moffat::fromFwhm(fwhm);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Truth> truths;
  for (int i = 0; i < 12; ++i) {
    // Positions on a 4 x 3 lattice; velocities off the grid points, within +-6 steps of the centre (tracks
    // of at most +-6 px, so the objects stay apart and inside).
    const double x = 18 + 32 * (i % 4) + 4 * u(rng), y = 18 + 32 * (i / 4) + 4 * u(rng);
    const Velocity v{(u(rng) - 0.5) * 12 * grid.stepPxS, (u(rng) - 0.5) * 12 * grid.stepPxS};
    truths.push_back({x, y, v});
    for (int k = 0; k < n; ++k) {
      const double xc = x + v.vx * dt[k], yc = y + v.vy * dt[k];
      for (int yy = static_cast<int>(yc) - 8; yy <= static_cast<int>(yc) + 8; ++yy)
        for (int xx = static_cast<int>(xc) - 8; xx <= static_cast<int>(xc) + 8; ++xx)
          if (xx >= 0 && yy >= 0 && xx < w && yy < h)
            cube.frames.frame(k)[static_cast<std::size_t>(yy) * w + xx] +=
                static_cast<float>(psf.pixelMean(xx - xc, yy - yc, 4));
    }
  }
  // No noise: the loss is the tracks' alone, not a draw of the noise.
  const stack::FilterKernel kernel = stack::makeFilterKernel(psf);
  for (std::size_t k = 0; k < cube.frames.frameCount(); ++k)
    stack::filterFrame(cube.frames.frame(k), w, h, kernel);
  cube.sigmaF = 1.0;
  cube.psfFwhmPx = fwhm;
  NullProgress progress;
  CancelToken cancel;
  search::SearchParams params;
  params.snrThreshold = 0.5;
  params.method = st::search::SearchMethod::Tree;
  const search::SearchResult tree = search::treeSearch(cube, grid, params, progress, cancel);
  std::vector<double> losses;
  for (const Truth& t : truths) {
    double exact = 0.0, fromTree = 0.0;
    for (int iy = 0; iy < nv; ++iy)
      for (int ix = 0; ix < nv; ++ix) {
        const Velocity v = grid.at(ix, iy);
        if (std::hypot(v.vx - t.v.vx, v.vy - t.v.vy) > 1.5 * grid.stepPxS) continue;
        const stack::StackResult st = stack::stackIpsa(cube.frames, v);
        for (int y = static_cast<int>(t.y) - 2; y <= static_cast<int>(t.y) + 3; ++y)
          for (int x = static_cast<int>(t.x) - 2; x <= static_cast<int>(t.x) + 3; ++x)
            if (std::hypot(x - t.x, y - t.y) <= 2.0) exact = std::max(exact, double(st.sum.at(x, y)));
      }
    for (const auto& c : tree.candidates)
      if (std::hypot(c.x - t.x, c.y - t.y) <= 2.0 &&
          std::hypot(c.v.vx - t.v.vx, c.v.vy - t.v.vy) <= 1.5 * grid.stepPxS)
        fromTree = std::max(fromTree, c.sum);
    if (exact > 0.0) losses.push_back(1.0 - fromTree / exact);
  }
  LossResult out;
  out.matched = static_cast<int>(losses.size());
  if (losses.empty()) return out;
  std::sort(losses.begin(), losses.end());
  out.median = losses[losses.size() / 2];
  out.worst = losses.back();
  const search::TreePlan plan = search::buildTreePlan(dt, grid);
  out.maxShiftErr = std::max(plan.maxAbsErrX, plan.maxAbsErrY);
  return out;
}

TEST(TreeSnrLoss, MeasuredLossMatchesTheTableAutoUsesAndFallsWithTheFwhm) {
  double previous = 1.0;
  std::printf("FWHM px | tree SNR loss vs exact: median, worst (12 objects) | table | max track error px\n");
  for (const double fwhm : {1.5, 2.0, 2.5, 3.5}) {
    const LossResult r = measureLoss(fwhm, 1500, 100, 17);
    std::printf("%.1f | %.1f%%, %.1f%% | %.1f%% | %d\n", fwhm, 100 * r.median, 100 * r.worst,
                100 * search::treeSnrLoss(fwhm), r.maxShiftErr);
    ASSERT_EQ(r.matched, 12) << "FWHM " << fwhm;
    EXPECT_EQ(r.maxShiftErr, 2);  // the paper's problem's tree (gpu/README.md)
    EXPECT_NEAR(r.worst, search::treeSnrLoss(fwhm), 0.006) << "FWHM " << fwhm;
    EXPECT_LE(r.median, r.worst);
    EXPECT_GT(r.median, 0.0);  // the tree does lose something: the test can fail
    EXPECT_LT(r.worst, previous + 0.002) << "FWHM " << fwhm;
    previous = r.worst;
  }
}

}  // namespace
}  // namespace st

// The tree search's SNR cost against the exact search (issue 16, part 3) on matched-filtered injected
// objects: Moffat (beta 4) sources of FWHM 1.5, 2, 2.5 and 3.5 px at their true sub-pixel positions (not
// rounded to the IPSA shifts), white noise, the paper's cadence (16.7 Hz) and grid design (neighbouring
// velocities 1 px apart at the ends of the span), both searches on the CPU. The loss of an object is
// 1 - SNR_tree / SNR_exact at its best candidate (within 2 px and 1.5 grid steps of the truth); per FWHM the
// median over 12 objects is held against search::treeSnrLoss (the table `auto` uses, method_choice.hpp)
// within 1.5 percentage points, and the tree's loss must fall as the PSF widens.
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

LossResult measureLoss(double fwhm, unsigned seed) {
  const int w = 128, h = 128, n = 300, nv = 15;
  const double cadence = 1.0 / 16.7;
  search::FilteredCube cube;
  cube.frames = FrameCube(w, h, n);
  for (int k = 0; k < n; ++k)
    cube.frames.info()[k].mjdMid = 60000.0 + k * cadence / kSecondsPerDay;
  std::mt19937 rng(seed);
  std::normal_distribution<float> g(0.0f, 1.0f);
  for (auto& p : cube.frames.pixels())
    p = g(rng);
  const std::vector<double> dt = cube.frames.timeOffsetsS();
  const double span = dt.back() - dt.front();
  const search::VelocityGrid grid{{0.3, -0.2}, 2.0 / span, nv, nv};
  const psf::Moffat psf = psf::Moffat::fromFwhm(fwhm);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Truth> truths;
  for (int i = 0; i < 12; ++i) {
    // Positions on a 4 x 3 lattice (no overlaps), velocities anywhere inside the grid (off-grid).
    const double x = 16 + 32 * (i % 4) + 4 * u(rng), y = 20 + 40 * (i / 4) + 4 * u(rng);
    const Velocity v{grid.centre.vx + (u(rng) - 0.5) * (nv - 3) * grid.stepPxS,
                     grid.centre.vy + (u(rng) - 0.5) * (nv - 3) * grid.stepPxS};
    truths.push_back({x, y, v});
    for (int k = 0; k < n; ++k) {
      const double xc = x + v.vx * dt[k], yc = y + v.vy * dt[k];
      for (int yy = static_cast<int>(yc) - 8; yy <= static_cast<int>(yc) + 8; ++yy)
        for (int xx = static_cast<int>(xc) - 8; xx <= static_cast<int>(xc) + 8; ++xx)
          if (xx >= 0 && yy >= 0 && xx < w && yy < h)
            cube.frames.frame(k)[static_cast<std::size_t>(yy) * w + xx] +=
                0.35f * static_cast<float>(psf.pixelMean(xx - xc, yy - yc, 4));
    }
  }
  NullProgress progress;
  CancelToken cancel;
  cube.sigmaF = stack::filterCube(cube.frames, stack::makeFilterKernel(psf), progress, cancel).sigmaF;
  cube.psfFwhmPx = fwhm;
  search::SearchParams params;
  params.snrThreshold = 5.0;
  params.method = "exact";
  const search::SearchResult exact = search::makeCpuBackend()->search(cube, grid, params, progress, cancel);
  params.method = "tree";
  const search::SearchResult tree = search::treeSearch(cube, grid, params, progress, cancel);
  auto best = [&](const search::SearchResult& r, const Truth& t) {
    double snr = 0.0;
    for (const auto& c : r.candidates)
      if (std::hypot(c.x - t.x, c.y - t.y) <= 2.0 &&
          std::hypot(c.v.vx - t.v.vx, c.v.vy - t.v.vy) <= 1.5 * grid.stepPxS)
        snr = std::max(snr, c.snr);
    return snr;
  };
  std::vector<double> losses;
  for (const Truth& t : truths) {
    const double e = best(exact, t), tr = best(tree, t);
    if (e < 7.0) continue;  // not a clear detection: no ratio
    losses.push_back(1.0 - tr / e);
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
    const LossResult r = measureLoss(fwhm, 17);
    std::printf("%.1f | %.1f%%, %.1f%% (%d matched) | %.1f%% | %d\n", fwhm, 100 * r.median, 100 * r.worst,
                r.matched, 100 * search::treeSnrLoss(fwhm), r.maxShiftErr);
    ASSERT_GE(r.matched, 10) << "FWHM " << fwhm;
    EXPECT_NEAR(r.median, search::treeSnrLoss(fwhm), 0.015) << "FWHM " << fwhm;
    EXPECT_LT(r.median, previous + 0.005) << "FWHM " << fwhm;
    previous = r.median;
  }
}

}  // namespace
}  // namespace st

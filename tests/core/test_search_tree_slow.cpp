// The tree search against the exact search at the paper's cadence (16.7 Hz), many injected objects at random
// (off-grid) velocities: SNR loss (median <= 3%, worst <= 10%) and nothing the exact search finds at
// SNR >= threshold + 1 is lost.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

#include "search_test_cubes.hpp"
#include "st/search/cpu_backend.hpp"

namespace st::search {
namespace {

const Candidate* nearestCandidate(const SearchResult& r, double x, double y, int radius) {
  return test::nearestFound(r, x, y, radius);
}

TEST(SearchTreeSlow, PaperCadenceInjectedObjects) {
  const psf::Moffat psf{psf::Moffat::radiusForFwhm(3.0, 4.0), 4.0};
  const int r = 5;
  const std::size_t frames = 300;
  std::vector<double> times(frames);
  for (std::size_t n = 0; n < frames; ++n)
    times[n] = static_cast<double>(n) / 16.7;
  const double span = times.back() - times.front();
  std::vector<double> losses;
  int exactStrong = 0;
  auto backend = makeCpuBackend();
  NullProgress progress;
  CancelToken cancel;
  for (unsigned seed = 0; seed < 2; ++seed) {
    FilteredCube fc;
    fc.frames = test::noiseCube(128, 128, times, 1.0, 500 + seed);
    const VelocityGrid grid{{0.0, 0.0}, 1.0 / span, 61, 61};  // +-30 px over the span
    const double p2 = test::sumP2(psf, r);
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> uv(-29.0 / span, 29.0 / span);
    std::uniform_real_distribution<double> usnr(9.0, 14.0);
    std::vector<std::pair<double, double>> at;
    for (int i = 0; i < 16; ++i) {
      const double x = 10.0 + 36.0 * (i % 4);
      const double y = 10.0 + 36.0 * (i / 4);
      const double alpha = usnr(rng) / (std::sqrt(static_cast<double>(frames)) * std::sqrt(p2));
      test::injectMoffat(fc.frames, psf, alpha, x, y, {uv(rng), uv(rng)});
      at.emplace_back(x, y);
    }
    test::matchedFilter(fc.frames, psf, r);
    fc.sigmaF = std::sqrt(p2);
    fc.psfFwhmPx = psf.fwhm();
    SearchParams params;
    const SearchResult exact = backend->search(fc, grid, params, progress, cancel);
    params.method = st::search::SearchMethod::Tree;
    const SearchResult tree = backend->search(fc, grid, params, progress, cancel);
    for (const auto& [x, y] : at) {
      const Candidate* e = nearestCandidate(exact, x, y, 3);
      ASSERT_NE(e, nullptr);
      const Candidate* t = nearestCandidate(tree, x, y, 3);
      ASSERT_NE(t, nullptr) << "object at " << x << "," << y << " lost";
      losses.push_back(1.0 - t->snr / e->snr);
    }
    for (const Candidate& e : exact.candidates) {
      if (e.snr < exact.snrThreshold + 1.0) continue;
      ++exactStrong;
      EXPECT_NE(nearestCandidate(tree, e.x, e.y, 6), nullptr) << "exact candidate at " << e.x << "," << e.y;
    }
  }
  std::sort(losses.begin(), losses.end());
  std::printf(
      "paper cadence: SNR loss over %zu objects: min %.4f median %.4f max %.4f; %d exact candidates >= "
      "threshold + 1 checked\n",
      losses.size(), losses.front(), losses[losses.size() / 2], losses.back(), exactStrong);
  EXPECT_LE(losses[losses.size() / 2], 0.03);
  EXPECT_LE(losses.back(), 0.10);
}

}  // namespace
}  // namespace st::search

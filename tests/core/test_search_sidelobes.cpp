// Sidelobes of bright moving sources (st/search/sidelobes.hpp): the model's predicted SNR against the IPSA
// sums measured on a noise-free matched-filtered cube; merging what a brighter source explains and keeping
// what it does not.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "search_test_cubes.hpp"
#include "st/search/cpu_backend.hpp"
#include "st/search/ipsa.hpp"
#include "st/search/sidelobes.hpp"

namespace st::search {
namespace {

constexpr int kW = 96;
constexpr int kH = 80;
constexpr int kStampR = 6;

struct Scene {
  FilteredCube fc;
  VelocityGrid grid;
};

/// 80 uneven frames over ~48 s, Moffat FWHM 3 px, noise sigma `sigma`; sources at grid velocities with the
/// given expected SNRs (paper detection_snr with sigma 1).
Scene scene(double sigma, const std::vector<std::tuple<double, double, int, int, double>>& sources) {
  const psf::Moffat psf{psf::Moffat::radiusForFwhm(3.0, 4.0), 4.0};
  Scene s;
  s.fc.frames = test::noiseCube(kW, kH, test::unevenTimes(80, 0.6, 4), sigma, 17);
  s.grid = VelocityGrid{{0.0, 0.0}, 1.0 / s.fc.frames.timeSpanS(), 41, 41};
  const double p2 = test::sumP2(psf, kStampR);
  for (const auto& [x, y, ivx, ivy, snr] : sources)
    test::injectMoffat(s.fc.frames, psf, snr / (std::sqrt(80.0) * std::sqrt(p2)), x, y, s.grid.at(ivx, ivy));
  test::matchedFilter(s.fc.frames, psf, kStampR);
  s.fc.sigmaF = std::sqrt(p2);  // unit white noise through the filter (and the SNR scale without noise)
  s.fc.psfFwhmPx = psf.fwhm();
  return s;
}

Candidate cellAt(const Scene& s, int x, int y, int ivx, int ivy) {
  Candidate c;
  c.x = x;
  c.y = y;
  c.ivx = ivx;
  c.ivy = ivy;
  c.v = s.grid.at(ivx, ivy);
  const IpsaCell cell = ipsaReference(s.fc.frames, s.fc.frames.timeOffsetsS(), x, y, c.v);
  c.sum = cell.sum;
  c.nIn = cell.nIn;
  c.snr = cell.nIn > 0 ? cell.sum / (s.fc.sigmaF * std::sqrt(cell.nIn)) : 0.0;
  return c;
}

TEST(Sidelobes, PredictedSnrMatchesTheMeasuredSumsOfCrossingTracks) {
  // Noise-free: every measured SNR is the source's response alone. Cells on tracks that cross the source's
  // at 1-20 grid steps of velocity, at the position where they meet it mid-span and off it. Tolerance: the
  // Gaussian stands for the Moffat's autocorrelation; within 0.04 x the source SNR (0.8 of 20), checked
  // where the response is at least 5% of it.
  const Scene s = scene(1e-9, {{48.0, 40.0, 20, 20, 20.0}});
  const Candidate source = cellAt(s, 48, 40, 20, 20);
  ASSERT_GT(source.snr, 18.0);
  const std::vector<double> dt = s.fc.frames.timeOffsetsS();
  int checked = 0;
  for (int dv = 1; dv <= 20; dv += 3) {
    for (int dx = -6; dx <= 6; dx += 2) {
      for (const auto& [ax, ay] : {std::pair{1, 0}, std::pair{0, 1}, std::pair{1, 1}, std::pair{-1, 1}}) {
        const Candidate cell = cellAt(s, 48 + dx * ay, 40 + dx * ax, 20 + dv * ax, 20 + dv * ay);
        if (cell.snr < 0.05 * source.snr) continue;
        const double predicted = sidelobeSnr(source, cell, dt, kW, kH, s.fc.psfFwhmPx);
        EXPECT_NEAR(predicted, cell.snr, 0.04 * source.snr)
            << "dv " << dv << " dx " << dx << " axis (" << ax << ", " << ay << ")";
        ++checked;
      }
    }
  }
  EXPECT_GT(checked, 40);
  // Tracks that never meet: nothing.
  EXPECT_EQ(sidelobeSnr(source, cellAt(s, 10, 10, 20, 20), dt, kW, kH, s.fc.psfFwhmPx), 0.0);
}

TEST(Sidelobes, MergesWhatTheBrighterSourceExplainsAndKeepsTheRest) {
  // A noise-free scene gives each cell's response to the source exactly; the candidates are then given
  // SNRs = that response + an independent part (a noise bump, or a real second object). Threshold 7: a
  // candidate whose independent part is below 7 is the source's sidelobe; one above 7 is kept, as is one
  // whose track never meets the source's.
  const Scene s = scene(1e-9, {{48.0, 40.0, 20, 20, 40.0}});
  const std::vector<double> dt = s.fc.frames.timeOffsetsS();
  Candidate source = cellAt(s, 48, 40, 20, 20);
  source.clusterCells = 100;
  const Candidate crossing = cellAt(s, 44, 40, 28, 20);  // meets the source's track mid-way to the end
  ASSERT_GT(crossing.snr, 5.0);
  Candidate bump = crossing;
  bump.snr += 3.0;  // sidelobe + a 3-sigma noise bump: above 7, explained by the source
  bump.clusterCells = 4;
  Candidate real = cellAt(s, 52, 40, 12, 20);
  ASSERT_GT(real.snr, 5.0);
  real.snr += 9.0;  // sidelobe + a real object of SNR 9
  Candidate far = cellAt(s, 10, 70, 20, 20);
  ASSERT_LT(far.snr, 1e-6);
  far.snr = 7.5;
  std::vector<Candidate> candidates{source, real, bump, far};
  std::sort(candidates.begin(), candidates.end(), [](const auto& a, const auto& b) { return a.snr > b.snr; });
  const std::size_t merged = mergeSidelobes(candidates, dt, kW, kH, s.fc.psfFwhmPx, 7.0);
  EXPECT_EQ(merged, 1u);
  ASSERT_EQ(candidates.size(), 3u);
  EXPECT_EQ(candidates[0].x, 48);
  EXPECT_EQ(candidates[0].clusterCells, 104);  // the sidelobe's cells counted in the source
  EXPECT_EQ(candidates[1].x, 52);              // the real one, still sorted
  EXPECT_EQ(candidates[2].x, 10);
}

}  // namespace
}  // namespace st::search

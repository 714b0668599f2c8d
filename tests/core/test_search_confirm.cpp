// Confirmation in a second cube (paper §4.5): prediction, window, SNR and the window's false-alarm
// probability.
#include <gtest/gtest.h>

#include "search_test_cubes.hpp"
#include "st/common/error.hpp"
#include "st/search/confirm.hpp"
#include "st/search/cpu_backend.hpp"
#include "st/stats/false_alarm.hpp"

namespace st::search {
namespace {

constexpr int kStamp = 6;

FilteredCube observation(double startS, unsigned seed, const psf::Moffat& psf, double alpha, double x0,
                         double y0, Velocity v, double t0Shift) {
  std::vector<double> t = test::unevenTimes(40, 0.5, seed);
  for (double& ti : t)
    ti += startS;
  FilteredCube fc;
  fc.frames = test::noiseCube(128, 96, t, 1.0, seed);
  // The source is at (x0, y0) at time t0Shift (s, same clock); shift to this cube's t_ref.
  const double tRefS = (fc.frames.tRefMjd() - 60000.0) * 86400.0;
  if (alpha > 0)
    test::injectMoffat(fc.frames, psf, alpha, x0 + v.vx * (tRefS - t0Shift), y0 + v.vy * (tRefS - t0Shift),
                       v);
  test::matchedFilter(fc.frames, psf, kStamp);
  fc.sigmaF = std::sqrt(test::sumP2(psf, kStamp));
  fc.psfFwhmPx = psf.fwhm();
  return fc;
}

TEST(SearchConfirm, FindsTheCandidateTwoAndAHalfMinutesLater) {
  const psf::Moffat psf{psf::Moffat::radiusForFwhm(3.0, 4.0), 4.0};
  const double p2 = test::sumP2(psf, kStamp);
  const double alpha = 15.0 / (std::sqrt(40.0) * std::sqrt(p2));  // expected SNR 15 per cube (paper §5.1)
  const Velocity truth{0.4, -0.2};
  // First cube: detect. Source at (30, 50) at t = 10 s.
  const FilteredCube c1 = observation(0.0, 1, psf, alpha, 30.0, 50.0, truth, 10.0);
  const double span = c1.frames.timeSpanS();
  const VelocityGrid grid{{0.0, 0.0}, 1.0 / span, 15, 15};
  auto backend = makeCpuBackend();
  NullProgress progress;
  CancelToken cancel;
  const SearchResult det = backend->search(c1, grid, SearchParams{}, progress, cancel);
  ASSERT_FALSE(det.candidates.empty());
  const Candidate& c = det.candidates[0];
  // Second cube 150 s later, fresh noise: the source has moved ~60 px.
  const FilteredCube c2 = observation(150.0, 2, psf, alpha, 30.0, 50.0, truth, 10.0);
  ConfirmRequest req;
  req.x = c.x;
  req.y = c.y;
  req.v = c.v;
  req.tRef1Mjd = det.tRefMjd;
  req.gridStepPxS = grid.stepPxS;
  const ConfirmResult conf = confirmCandidate(c2, req, progress, cancel);
  EXPECT_NEAR(conf.dtS, 150.0, 0.5);
  const double trueX2 = 30.0 + truth.vx * ((conf.tRef2Mjd - 60000.0) * 86400.0 - 10.0);
  const double trueY2 = 50.0 + truth.vy * ((conf.tRef2Mjd - 60000.0) * 86400.0 - 10.0);
  EXPECT_LE(std::abs(conf.predX - trueX2), 3.0 * conf.sigmaPosPx);  // the prediction is within its error
  EXPECT_NEAR(conf.best.x, trueX2, 1.0);
  EXPECT_NEAR(conf.best.y, trueY2, 1.0);
  EXPECT_TRUE(conf.confirmed);
  EXPECT_GT(conf.snr, 0.8 * 15.0);
  EXPECT_LT(conf.snr, 1.15 * 15.0);
  EXPECT_EQ(conf.trials.nx, conf.width);
  EXPECT_EQ(conf.trials.nvx, conf.grid.nvx);
  EXPECT_GE(conf.grid.nvx, 3);
  EXPECT_NEAR(conf.fap,
              stats::confirmationFap(conf.snr, conf.width, conf.height, conf.grid.nvx, conf.grid.nvy),
              1e-300);
  // The window is much smaller than the detection search, so the FAP at equal SNR is smaller too.
  EXPECT_LT(conf.trials.total(), 0.1 * det.trials.total());
}

TEST(SearchConfirm, NoiseOnlyIsNotConfirmed) {
  const psf::Moffat psf{psf::Moffat::radiusForFwhm(3.0, 4.0), 4.0};
  const FilteredCube c2 = observation(600.0, 3, psf, 0.0, 0, 0, {}, 0);
  ConfirmRequest req;
  req.x = 40;
  req.y = 40;
  req.v = {0.01, 0.0};
  req.tRef1Mjd = 60000.0;
  req.gridStepPxS = 0.05;
  NullProgress progress;
  CancelToken cancel;
  const ConfirmResult conf = confirmCandidate(c2, req, progress, cancel);
  EXPECT_FALSE(conf.confirmed);
  EXPECT_LT(conf.snr, conf.snrThreshold);
  req.x = 5000;  // predicted far outside the frame
  EXPECT_THROW(confirmCandidate(c2, req, progress, cancel), InputError);
  req.x = 40;
  req.gridStepPxS = 0.0;
  EXPECT_THROW(confirmCandidate(c2, req, progress, cancel), InputError);
}

}  // namespace
}  // namespace st::search

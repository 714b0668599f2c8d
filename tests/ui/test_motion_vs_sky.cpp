// The captions' candidate (motion_vs_sky.hpp shownTrack): the search cell until a co-moving fit that
// converged is accepted, then the fit's position, velocity and SNR (the figure dialog's captions, the
// sky-and-object figure's stacks and the fit panel's header use it; they kept the search cell's values).
#include <gtest/gtest.h>

#include "motion_vs_sky.hpp"
#include "ui_test_support.hpp"

using namespace st;
using namespace st::ui;

TEST(ShownTrack, TheAcceptedConvergedFitSupersedesTheSearchCell) {
  Observation obs;
  obs.setRaw(std::make_shared<const FrameCube>(test::movingDotCube(100, 100, 10, {}, 50, 50)), "t");
  auto result = std::make_shared<search::SearchResult>();
  search::Candidate c;
  c.x = 50;
  c.y = 40;
  c.v = {1.0, 0.0};
  c.snr = 8.0;
  c.nIn = 10;
  result->candidates.push_back(c);
  obs.setResult(result);
  ShownTrack t = shownTrack(obs, 0, c);
  EXPECT_FALSE(t.fitted);
  EXPECT_EQ(t.x, 50.0);
  EXPECT_EQ(t.snr, 8.0);
  EXPECT_TRUE(describeShownTrack(obs, t).startsWith("search SNR 8.0, rate 1 px/s vs sky"))
      << describeShownTrack(obs, t).toStdString();

  candidate::FitSummary fit;
  fit.status = fit::FitStatus::Converged;
  fit.x = 50.4;
  fit.y = 40.2;
  fit.v = {1.5, 2.0};
  fit.snr = 9.3;
  obs.setCandidateFit(0, fit);
  t = shownTrack(obs, 0, c);
  EXPECT_TRUE(t.fitted);
  EXPECT_EQ(t.x, 50.4);
  EXPECT_EQ(t.y, 40.2);
  EXPECT_EQ(t.v, (Velocity{1.5, 2.0}));
  EXPECT_TRUE(describeShownTrack(obs, t).startsWith("fit SNR 9.3, rate 2.5 px/s vs sky"))  // |(1.5, 2)| = 2.5
      << describeShownTrack(obs, t).toStdString();

  // A fit that did not converge does not replace the search cell.
  fit.status = fit::FitStatus::Diverged;
  obs.setCandidateFit(0, fit);
  EXPECT_FALSE(shownTrack(obs, 0, c).fitted);
}
